"""The MUSHROOMS scheduler: prune, block-division MILP, TSP order, real times.

``milp_schedule`` runs the paper's three steps on a
:class:`~..problem.PlanningProblem`:

1. prune the observable grid to a shortlist (max weighted coverage);
2. merge pixels into weighted cells and solve the block-division MILP;
3. order each block by a TSP over the true slews, then recompute every
   exposure time with the real overheads.  When a block overruns so that a
   field would leave its window, the MILP is solved again with a gap before
   the offending block (or a longer block) — at most ``max_retries`` times;
   after that the offending fields are dropped, so the plan is always
   executable.

When the solver finds no incumbent before its deadline, the greedy plan is
returned with status ``no_incumbent_greedy_fallback``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from .model import (BlockModel, BlockParams, Candidates, DecodedBlock, build_block_model, decode_blocks,
                     heuristic_start)
from ...sequences import require_pair
from ...sky.cells import Cells, merge_cells
from ...config import PlanningConfig
from .ordering import order_fields
from ...plan.document import Observation
from ...sky.footprints import Footprints
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from .prune import schedulable_rows, shortlist_fields
from ...telescope.slew import overhead_time
from ..milp.solvers import SolveResult, solve_milp

__all__ = ["milp_schedule", "shortlist_footprints", "make_candidates", "time_blocks", "TimedBlocks"]

log = logging.getLogger(__name__)

#: Extra seconds added on top of a measured overrun when a block is re-solved.
RETRY_MARGIN_S = 30.0


def shortlist_footprints(footprints: Footprints, rows: np.ndarray) -> Footprints:
    """Footprints of the given rows, in that order (vectorised CSR slice)."""
    rows = np.asarray(rows, dtype=np.int64)
    counts = footprints.indptr[rows + 1] - footprints.indptr[rows]
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    offsets = np.repeat(footprints.indptr[rows] - indptr[:-1], counts)
    indices = footprints.indices[np.arange(indptr[-1]) + offsets]
    return Footprints(footprints.nside, footprints.field_ids[rows], indptr, indices)


def make_candidates(problem: PlanningProblem, rows: np.ndarray, min_length_s: float) -> Candidates:
    """(field, window) pairs of the shortlisted rows long enough for a block.

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray
        Shortlisted rows of ``problem.field_ids``.
    min_length_s : float
        Windows shorter than this (after clipping to the horizon) are dropped.

    Returns
    -------
    Candidates
        ``field`` indexes ``rows``.
    """
    w = problem.windows
    ids = problem.field_ids[rows]
    if ids.size == 0:
        return Candidates(np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    order = np.argsort(ids)
    pos = np.clip(np.searchsorted(ids, w.field_ids, sorter=order), 0, len(ids) - 1)
    match = ids[order[pos]] == w.field_ids
    start = np.clip(w.start, 0.0, problem.horizon_s)
    end = np.clip(w.end, 0.0, problem.horizon_s)
    keep = match & (end - start >= min_length_s)
    sel = np.flatnonzero(keep)
    sel = sel[np.lexsort((start[sel], order[pos[sel]]))]
    return Candidates(order[pos[sel]].astype(np.int64), start[sel], end[sel])


@dataclass(frozen=True)
class TimedBlocks:
    """Exposures of the decoded blocks at their real times.

    Attributes
    ----------
    observations : list of Observation
        In time order.
    offending : tuple or None
        ``(block, candidate, excess_s)`` of the first exposure leaving its
        window (or the horizon), None when all fit.
    real_start, real_duration : numpy.ndarray
        Per block: real start of the first exposure (s) and real span (s)
        from it to the end of the block (last exposure end plus t_slew).
    """

    observations: list[Observation]
    offending: tuple[int, int, float] | None
    real_start: np.ndarray
    real_duration: np.ndarray


def time_blocks(problem: PlanningProblem, blocks: list[DecodedBlock], rows: np.ndarray,
                candidates: Candidates, orders: list[np.ndarray]) -> TimedBlocks:
    """Real exposure times of ordered blocks, as early as the overheads allow.

    A block starts no earlier than its planned start (its fields' windows
    open by then); within it, each exposure follows the previous one after
    the true overhead (:func:`~...telescope.slew.overhead_time`); a second-filter
    exposure also waits until the cadence since its first-filter exposure
    has passed.

    Parameters
    ----------
    problem : PlanningProblem
    blocks : list of DecodedBlock
        In time order.
    rows : numpy.ndarray
        Shortlisted rows of the problem.
    candidates : Candidates
    orders : list of numpy.ndarray
        For each block, the permutation of its candidates.

    Returns
    -------
    TimedBlocks
    """
    cfg = problem.config
    f1, f2 = cfg.filters
    exp = cfg.exposure_s
    obs: list[Observation] = []
    offending: tuple[int, int, float] | None = None
    prev: tuple[float, float, str, float] | None = None   # ra, dec, filter, end
    real_start = np.zeros(len(blocks))
    real_duration = np.zeros(len(blocks))
    for b, (block, order) in enumerate(zip(blocks, orders)):
        cand = block.candidates[order]
        prow = rows[candidates.field[cand]]
        ra, dec = problem.ra[prow], problem.dec[prow]
        first = np.empty(len(cand))
        second = np.empty(len(cand))
        for pass_no, flt, times in ((0, f1, first), (1, f2, second)):
            for m in range(len(cand)):
                if prev is None:
                    t = block.start_s
                else:
                    oh = float(overhead_time(prev[0], prev[1], ra[m], dec[m], cfg.slew,
                                             cfg.filter_change_s if prev[2] != flt else 0.0))
                    t = prev[3] + oh
                if pass_no == 0 and m == 0:
                    t = max(t, block.start_s)
                if pass_no == 1:
                    t = max(t, first[m] + cfg.cadence_s)
                times[m] = t
                prev = (float(ra[m]), float(dec[m]), flt, t + exp)
        real_start[b] = first[0]
        real_duration[b] = second[-1] + exp + cfg.slew_estimate_s - first[0]
        for m, k in enumerate(cand):
            fid = int(problem.field_ids[prow[m]])
            for flt, t in ((f1, first[m]), (f2, second[m])):
                obs.append(Observation(fid, float(ra[m]), float(dec[m]), flt, float(t), exp, b))
                excess = max(candidates.start[k] - t, t + exp - candidates.end[k], t + exp - problem.horizon_s)
                if excess > 1e-6 and offending is None:
                    offending = (b, int(k), float(excess))
    obs.sort(key=lambda o: o.start)
    return TimedBlocks(obs, offending, real_start, real_duration)


def _order_blocks(problem: PlanningProblem, blocks: list[DecodedBlock], rows: np.ndarray,
                  candidates: Candidates) -> list[np.ndarray]:
    orders = []
    for block in blocks:
        prow = rows[candidates.field[block.candidates]]
        orders.append(order_fields(problem.ra[prow], problem.dec[prow], problem.config.slew))
    return orders


def _drop_offenders(problem: PlanningProblem, blocks: list[DecodedBlock], rows: np.ndarray,
                    candidates: Candidates, orders: list[np.ndarray]) -> tuple[TimedBlocks, list[int]]:
    """Remove offending fields one at a time until every exposure fits its window."""
    dropped: list[int] = []
    blocks, orders = list(blocks), list(orders)
    while True:
        timed = time_blocks(problem, blocks, rows, candidates, orders)
        if timed.offending is None:
            return timed, dropped
        b, k, _ = timed.offending
        dropped.append(int(problem.field_ids[rows[candidates.field[k]]]))
        members = blocks[b].candidates[orders[b]]
        keep = members != k
        if keep.any():
            new = members[keep]
            blocks[b] = replace(blocks[b], candidates=new)
            orders[b] = np.arange(new.size)
        else:
            del blocks[b], orders[b]
            blocks = [replace(blk, index=i) for i, blk in enumerate(blocks)]


def _fallback(problem: PlanningProblem, should_stop: StopCheck | None, res: SolveResult,
              details: dict, t_wall: float) -> ScheduleResult:
    from ..greedy.schedule import greedy_schedule

    log.warning("MILP (%s) found no incumbent (%s); using the greedy plan", res.backend, res.status)
    greedy = greedy_schedule(problem, should_stop)
    details.update(greedy_details=greedy.details)
    return ScheduleResult(tuple(greedy.observations), f"milp:{res.backend}", "no_incumbent_greedy_fallback",
                          None, time.perf_counter() - t_wall, details, solver_status=res.status)


def _prepare(problem: PlanningProblem, params: BlockParams) -> tuple[np.ndarray, Cells, Candidates]:
    """The shortlisted rows, their merged cells and the block candidates."""
    # the shortest block any field could join: b_size fields, or all fields if fewer
    n_sched = len(schedulable_rows(problem, params.least_duration_s(1)))
    b_eff = max(1, min(params.b_size, n_sched))
    min_window = params.least_duration_s(b_eff)
    rows = shortlist_fields(problem, min_window_s=min_window)
    b_eff = max(1, min(params.b_size, len(rows)))
    min_window = params.least_duration_s(b_eff)
    fp = shortlist_footprints(problem.footprints, rows)
    cells = merge_cells(fp, problem.prob)
    return rows, cells, make_candidates(problem, rows, min_window)


def _make_room(timed: TimedBlocks, blocks: list[DecodedBlock], gaps: np.ndarray, extra: np.ndarray,
               attempt: int) -> None:
    """Before a re-solve, widen ``gaps`` / ``extra`` (in place) where the offending block overran.

    The paper's fix: more time before the offending block (inherited delay),
    or a longer block when the block itself overran its estimate.
    """
    b, k, excess = timed.offending
    late = timed.real_start[b] - blocks[b].start_s
    over = timed.real_duration[b] - blocks[b].duration_s
    if b > 0 and late > 1e-6:
        gaps[b - 1] += late + RETRY_MARGIN_S
    if over > 1e-6:
        extra[b] += over + RETRY_MARGIN_S
    if not (b > 0 and late > 1e-6) and not over > 1e-6:
        extra[b] += excess + RETRY_MARGIN_S
    log.info("MILP retry %d: block %d overruns a window by %.0f s (late %.0f s, over %.0f s)",
             attempt + 1, b, excess, late, over)


def _attempt_record(model: BlockModel, start: np.ndarray | None, res: SolveResult) -> dict:
    """The diagnostics of one solve (``details["attempts"]``)."""
    return {"start_objective": None if start is None else model.coverage_objective(start),
            "status": res.status, "objective": res.objective, "bound": res.bound, "gap": res.gap,
            "runtime_s": round(res.runtime_s, 3), "time_to_first_s": res.time_to_first_s,
            "time_to_gap_s": res.time_to_gap_s}


def _executable(problem: PlanningProblem, model: BlockModel, x: np.ndarray, rows: np.ndarray,
                candidates: Candidates) -> tuple[list[DecodedBlock], TimedBlocks, TimedBlocks, list[int], float]:
    """Decode, order and time a solution: (blocks, as timed, its executable version, dropped fields, coverage).

    The executable version is what the solve gives once the fields pushed out
    of their windows are dropped.
    """
    blocks = decode_blocks(model, x)
    orders = _order_blocks(problem, blocks, rows, candidates)
    timed = time_blocks(problem, blocks, rows, candidates, orders)
    valid, dropped = ((timed, []) if timed.offending is None
                      else _drop_offenders(problem, blocks, rows, candidates, orders))
    coverage = problem.footprints.coverage({o.field_id for o in valid.observations}, problem.prob)
    return blocks, timed, valid, dropped, coverage


#: With a whole-call budget (``milp_schedule(total_s=...)``), no re-solve starts with less than this (s) left.
MIN_RESOLVE_S = 0.2


def milp_schedule(problem: PlanningProblem, should_stop: StopCheck | None = None,
                  total_s: float | None = None, cutoff: float | None = None) -> ScheduleResult:
    """Plan the horizon with MUSHROOMS (pruning, block MILP, TSP, post-processing).

    Parameters
    ----------
    problem : PlanningProblem
        Candidate fields, footprints, windows, config (``n_fields``,
        ``n_blocks_max``, ``penalty``, ``block_gap_s``, ``milp_backend``,
        ``time_limit_s``, ``mip_gap``, ``threads``, ``max_retries``, ...).
    should_stop : callable, optional
        Polled by the solver; True interrupts it (the incumbent is used).
    total_s : float, optional
        Budget (s, on ``problem.clock``) of the whole call, re-solves included (a
        portfolio's stage): each solve gets at most what is left of it, and
        no re-solve starts with less than :data:`MIN_RESOLVE_S` left.  None:
        the first solve gets ``time_limit_s``, each re-solve its own share.
    cutoff : float, optional
        Coverage the plan must beat to matter (a portfolio's best plan so
        far plus ``min_gain``): the solve stops as soon as its bound proves
        no block plan reaches it (the executable plan covers no more than the
        MILP's objective), and the result is then empty, status ``cutoff``.

    Returns
    -------
    ScheduleResult
        ``solver`` is ``milp:highs`` or ``milp:gurobi``; ``status`` the
        solver's (``optimal``, ``time_limit``, ``interrupted``) or
        ``no_incumbent_greedy_fallback`` / ``no_candidates``; ``mip_gap``
        the final relative gap, ``mip_bound`` the solver's bound and
        ``dropped_by_slews`` the fields the real timing dropped;
        ``details`` holds model size, cells vs pixels, times to first
        incumbent and to 1 % gap, the attempts and retries.
    """
    require_pair(problem.config.filters, "block MILP")
    t_wall, t_budget = time.perf_counter(), problem.clock.mark()
    cfg: PlanningConfig = problem.config
    params = BlockParams.from_config(cfg)
    rows, cells, candidates = _prepare(problem, params)
    t_prep = time.perf_counter() - t_wall
    details: dict = {
        "shortlist": int(len(rows)), "n_candidates": len(candidates), "n_pixels": cells.n_pixels,
        "n_cells": cells.n_cells, "b_size": params.b_size, "n_blocks_max": params.n_blocks,
        "prepare_s": round(t_prep, 4),
    }
    if len(candidates) == 0 or cells.n_cells == 0:
        return ScheduleResult((), "milp:none", "no_candidates", None, time.perf_counter() - t_wall, details)

    attempts: list[dict] = []
    best: tuple[float, TimedBlocks, list[int], SolveResult, int] | None = None
    gaps, extra = params.gaps.copy(), params.extra.copy()
    for attempt in range(cfg.max_retries + 1):
        p = replace(params, gaps=gaps.copy(), extra=extra.copy())
        model: BlockModel = build_block_model(candidates, cells, len(rows), p)
        start = heuristic_start(model, candidates, cells, p)
        # a re-solve only moves blocks a little: it gets a third of the limit (at least 5 s)
        limit = cfg.time_limit_s if attempt == 0 else max(min(5.0, cfg.time_limit_s), cfg.time_limit_s / 3)
        if total_s is not None:
            left = total_s - problem.clock.since(t_budget)  # (A1)
            if attempt > 0 and left < MIN_RESOLVE_S:
                break  # the stage's budget is spent: the best plan so far
            limit = min(limit, max(left, 0.01))
        res = solve_milp(model.milp, cfg.milp_backend, limit, cfg.mip_gap, cfg.threads, should_stop,
                         start=start, cutoff=cutoff, clock=problem.clock)
        attempts.append(_attempt_record(model, start, res))
        if res.status == "cutoff":  # (V6) its own relaxation: no block plan beats the cutoff
            details.update(attempts=attempts, cutoff=cutoff)
            return ScheduleResult((), f"milp:{res.backend}", "cutoff", res.gap, time.perf_counter() - t_wall,
                                  details, mip_bound=res.bound)
        if attempt == 0:
            details.update(model_size=model.milp.size(), backend=res.backend, backend_note=res.note,
                           time_to_first_s=res.time_to_first_s, time_to_gap_s=res.time_to_gap_s)
        if not res.has_solution:
            details["attempts"] = attempts
            return _fallback(problem, should_stop, res, details, t_wall)
        blocks, timed, valid, dropped, coverage = _executable(problem, model, res.x, rows, candidates)
        attempts[-1].update(coverage=coverage, dropped_fields=dropped)
        if best is None or coverage >= best[0] - 1e-12:  # ties: the later, re-solved plan
            best = (coverage, valid, dropped, res, attempt)
        if timed.offending is None:
            break
        interrupted = res.status == "interrupted" or (should_stop is not None and should_stop())
        if attempt == cfg.max_retries or interrupted:
            break
        _make_room(timed, blocks, gaps, extra, attempt)

    # the best executable plan over the attempts (a re-solve may end worse than
    # the first solve with its offending fields dropped)
    assert best is not None
    _, timed, dropped, res, chosen = best
    if dropped:
        log.info("MILP: dropped %d field(s) that real slews pushed out of their windows", len(dropped))
    details.update(
        attempts=attempts, retries=len(attempts) - 1, chosen_attempt=chosen,
        objective=res.objective, n_blocks=len({o.block for o in timed.observations}),
        solve_s=round(sum(a["runtime_s"] for a in attempts), 3),
    )
    return ScheduleResult(
        observations=tuple(timed.observations),
        solver=f"milp:{res.backend}",
        status=res.status,
        mip_gap=res.gap,
        runtime_s=time.perf_counter() - t_wall,
        details=details,
        mip_bound=res.bound,
        dropped_by_slews=tuple(dropped),
    )
