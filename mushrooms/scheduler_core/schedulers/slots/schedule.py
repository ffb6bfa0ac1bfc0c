"""The slot scheduler: a portfolio of slot grids, warm-started, post-processed.

``slot_schedule`` shortlists the fields (the block MILP's pruning, plus the
fields of a given start plan), solves the slot-assignment MILP
(:mod:`.model`) on a small portfolio of grids (``slot_positions`` × the
two phases) within one time budget, and turns the best solutions into
executable exposures with the real overheads:

- each block is observed in a TSP order over the true slews when that
  order keeps every exposure inside its window, else in the MILP's
  position order;
- every exposure starts as early as the real overheads, the cadence and the
  opening of its window allow;
- a field with an exposure still outside its window is dropped (both
  exposures), and the block is timed again.

Post-processing can only lose coverage, so the grids are post-processed in
decreasing order of their MILP objective until the best executable plan
covers at least the next grid's objective: the plan kept is the best of the
portfolio after post-processing.

A start plan (normally greedy's) is mapped onto each grid where it fits: each
of its fields goes to the free eligible slot nearest in time to its first
exposure.  The solver starts from that incumbent, so its result is never
worse than the start mapped onto the grid.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from ...sequences import require_pair
from ...sky.cells import merge_cells
from ...config import PlanningConfig
from ..blocks.ordering import order_fields
from ...plan.document import Observation
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from ..blocks.model import cadence_block_size
from ..blocks.prune import shortlist_fields
from ...telescope.slew import overhead_time
from .model import (SlotGrid, SlotInstance, SlotModel, build_slot_model, decode_slots, make_slot_grid,
                    observable_segments, slot_instance, start_vector)
from ..milp.solvers import SolveResult, resolve_backend, solve_milp

__all__ = ["slot_schedule", "slot_rows", "slot_portfolio", "grid_positions", "map_start", "time_slot_plan", "GridSolution"]

log = logging.getLogger(__name__)

#: Budget (s) below which no further grid is started.
MIN_SOLVE_S = 0.3
#: Each grid's time limit is the budget left divided by min(grids left, this).
PORTFOLIO_SPLIT = 3


def slot_rows(problem: PlanningProblem, start_fields: np.ndarray | None = None) -> np.ndarray:
    """Rows the slot model schedules: the pruning shortlist plus a start plan's fields.

    Only fields with a window long enough for their sequence in one window
    (``(k - 1) cadence + exposure``) enter the shortlist.
    """
    cfg = problem.config
    rows = shortlist_fields(problem, min_window_s=(len(cfg.filters) - 1) * cfg.cadence_s + cfg.exposure_s)
    if start_fields is not None and len(start_fields):
        extra = np.flatnonzero(np.isin(problem.field_ids, np.asarray(start_fields)))
        rows = np.union1d(rows, extra)
    return np.asarray(rows, np.int64)


def grid_positions(config: PlanningConfig) -> list[int]:
    """Positions per block of the portfolio's grids: n* first, then ``slot_positions``.

    n* = ``ceil((c - t_filt) / s)`` (:func:`..blocks.model.cadence_block_size`) is
    the fewest positions whose pass and filter change fill the cadence:
    with fewer, a block idles ``c - n s - t_filt`` between its passes (G1).
    It is added only when ``slot_positions`` lacks it (the default list
    holds 6, n* at 300 s: the default portfolio is unchanged; 9 at 180 s).
    """
    n_star = cadence_block_size(config)
    listed = [int(n) for n in config.slot_positions]
    return listed if n_star in listed else [n_star] + listed


def slot_portfolio(problem: PlanningProblem, rows: np.ndarray) -> list[SlotGrid]:
    """The grids solved: :func:`grid_positions` × phases ``start``, ``end``."""
    segments = observable_segments(problem, rows)
    grids = []
    for n in grid_positions(problem.config):
        for phase in ("start", "end"):
            g = make_slot_grid(segments, problem.config, int(n), phase)
            if g.n_slots:
                grids.append(g)
    return grids


def map_start(instance: SlotInstance, start: dict[int, float]) -> np.ndarray:
    """Pairs placing a start plan's fields on the grid.

    Parameters
    ----------
    instance : SlotInstance
    start : dict
        Model field index -> first exposure start (s) in the start plan.

    Returns
    -------
    numpy.ndarray
        Pair indices, at most one per field and per slot: fields in the
        start plan's time order, each on the free eligible slot nearest
        in time; fields that no free slot admits are left out.
    """
    taken = np.zeros(instance.grid.n_slots, bool)
    chosen = []
    t1 = instance.grid.t1
    for f, t in sorted(start.items(), key=lambda kv: kv[1]):
        k = np.flatnonzero((instance.pair_field == f) & ~taken[instance.pair_slot])
        if k.size == 0:
            continue
        best = k[np.argmin(np.abs(t1[instance.pair_slot[k]] - t))]
        taken[instance.pair_slot[best]] = True
        chosen.append(int(best))
    return np.asarray(chosen, np.int64)


@dataclass
class GridSolution:
    """One grid's solve: the model, the solver's result and the mapped start's objective."""

    model: SlotModel
    result: SolveResult
    start_objective: float | None


def _block_times(problem: PlanningProblem, order: np.ndarray, lbs: np.ndarray, block_start: float,
                 prev: tuple[float, float, str, float] | None, exp: np.ndarray) -> np.ndarray:
    """Earliest real starts (k, m) of a block's ``k`` passes in the given field order.

    ``lbs`` (k, m): each exposure's window opening; ``exp`` (m,): each field's
    exposure (s).  A visit waits the cadence after the field's visit in the
    pass before.
    """
    cfg = problem.config
    ra, dec = problem.ra[order], problem.dec[order]
    times = np.empty((len(cfg.filters), order.size))
    for p, flt in enumerate(cfg.filters):
        for m in range(order.size):
            t = block_start if prev is None else prev[3] + float(overhead_time(
                prev[0], prev[1], ra[m], dec[m], cfg.slew, cfg.filter_change_s if prev[2] != flt else 0.0))
            t = max(t, lbs[p, m], block_start)
            if p > 0:
                t = max(t, times[p - 1, m] + cfg.cadence_s)
            times[p, m] = t
            prev = (float(ra[m]), float(dec[m]), flt, t + float(exp[m]))
    return times


def _time_block(problem: PlanningProblem, inst: SlotInstance, pairs: list[int], T: float,
                prev: tuple[float, float, str, float] | None, pair_exp: np.ndarray, dropped: list[int]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool] | None:
    """Time one block's pairs: (rows in observing order, their exposures, starts (k, m), TSP order used).

    The TSP order over the true slews is tried first, then the MILP's
    position order; when neither keeps every exposure inside its window
    (and a sequence within the pair separation), the first offending field
    of the MILP order is dropped (its ID appended to ``dropped``) and the
    block timed again.  None when no field is left.
    """
    cfg = problem.config
    w = problem.windows
    while pairs:
        k = np.asarray(pairs)
        prow = inst.rows[inst.pair_field[k]]
        win = inst.windows()[k]  # (m, k passes)
        orders = [np.arange(k.size)]
        if k.size > 1:
            tsp = order_fields(problem.ra[prow], problem.dec[prow], cfg.slew)
            if not np.array_equal(tsp, orders[0]):
                orders.insert(0, tsp)
        kexp = pair_exp[k]
        for o in orders:
            exp = kexp[o]
            times = _block_times(problem, prow[o], w.start[win[o]].T, T, prev, exp)
            ends = np.minimum(w.end[win[o]].T, problem.horizon_s)
            bad = np.any(times + exp[None, :] > ends + 1e-6, axis=0)
            if times.shape[0] > 2:  # (G3) the sequence within the pair separation
                bad |= times[-1] - times[0] > cfg.pair_separation_s + 1e-6
            if not bad.any():
                return prow[o], exp, times, len(orders) == 2 and o is orders[0]
        # neither order fits: drop the first offending field of the MILP order
        offender = int(np.flatnonzero(bad)[0])
        dropped.append(int(problem.field_ids[prow[o][offender]]))
        del pairs[int(o[offender])]
    return None


def time_slot_plan(problem: PlanningProblem, model: SlotModel, x: np.ndarray
                   ) -> tuple[list[Observation], list[int], int]:
    """Executable exposures of a slot solution with the real overheads.

    Parameters
    ----------
    problem : PlanningProblem
    model : SlotModel
    x : numpy.ndarray
        Solution vector.

    Returns
    -------
    observations : list of Observation
        In time order: every chosen field once per filter of the sequence.
    dropped : list of int
        Field IDs dropped because an exposure fell outside its window.
    n_tsp : int
        Blocks observed in the TSP order (the others keep the MILP's order).
    """
    cfg = problem.config
    inst = model.instance
    problem.clock.step("timing", len(cfg.filters) * int(np.count_nonzero(x[:inst.n_pairs] > 0.5)))  # (A3) per exposure
    pair_exp = inst.exposures(cfg.exposure_s)  # each pair's own exposure (the menu's, or exposure_s)
    obs: list[Observation] = []
    dropped: list[int] = []
    prev: tuple[float, float, str, float] | None = None
    n_tsp = 0
    for b, (j, pairs) in enumerate(decode_slots(model, x)):
        timed = _time_block(problem, inst, list(pairs), float(inst.grid.block_start[j]), prev, pair_exp, dropped)
        if timed is None:
            continue
        rows_o, exp, times, tsp = timed
        n_tsp += int(tsp)
        for m, r in enumerate(rows_o):
            fid, ra, dec = int(problem.field_ids[r]), float(problem.ra[r]), float(problem.dec[r])
            for p, flt in enumerate(cfg.filters):
                obs.append(Observation(fid, ra, dec, flt, float(times[p, m]), float(exp[m]), b))
        last = rows_o[-1]
        prev = (float(problem.ra[last]), float(problem.dec[last]), cfg.filters[-1], float(times[-1, -1] + exp[-1]))
    obs.sort(key=lambda ob: ob.start)
    return obs, dropped, n_tsp


def slot_schedule(
    problem: PlanningProblem,
    should_stop: StopCheck | None = None,
    start: ScheduleResult | None = None,
    time_limit_s: float | None = None,
    pixel_weight: np.ndarray | None = None,
    pair_weight: "callable | None" = None,
) -> ScheduleResult:
    """Plan the horizon with the slot-assignment MILP on a portfolio of grids.

    Parameters
    ----------
    problem : PlanningProblem
        Uses ``config.slot_positions``, ``slot_margin_s``, ``milp_backend``,
        ``mip_gap``, ``threads``, ``penalty`` and ``time_limit_s``.
    should_stop : callable, optional
        Polled by the solver; True interrupts the portfolio (the best plan
        found so far is returned, status ``interrupted``).
    start : ScheduleResult, optional
        A plan (e.g. greedy's) given to every grid as the starting incumbent
        where it fits.
    time_limit_s : float, optional
        Budget (s, on ``problem.clock``: wall or work seconds) for the whole
        portfolio (default ``config.time_limit_s``); each grid gets the time left divided by
        the grids left, at most :data:`PORTFOLIO_SPLIT` (later grids are
        skipped when less than :data:`MIN_SOLVE_S` is left).
    pixel_weight : numpy.ndarray, optional
        Objective weight per pixel (default the probability); the plan's
        reported coverage is always the probability.
    pair_weight : callable, optional
        ``pair_weight(problem, instance) -> (K,) array`` of extra objective
        weight per eligible (field, slot) pair.

    Returns
    -------
    ScheduleResult
        ``solver`` ``slots:highs`` / ``slots:gurobi``; ``grid`` the chosen
        grid, ``mip_bound`` its solver's bound, ``dropped_by_slews`` the
        fields the real timing dropped; ``details`` hold the per-grid
        objectives, bounds and times and the mapped start's objective.
    """
    require_pair(problem.config.filters, "slot MILP", longer=True)
    t_wall, t_budget = time.perf_counter(), problem.clock.mark()
    cfg: PlanningConfig = problem.config
    budget = cfg.time_limit_s if time_limit_s is None else float(time_limit_s)
    backend = resolve_backend(cfg.milp_backend)  # once: the licence probe costs time
    start_first: dict[int, float] = {}
    if start is not None:
        for o in start.observations:
            start_first[o.field_id] = min(o.start, start_first.get(o.field_id, np.inf))
    rows = slot_rows(problem, np.asarray(list(start_first), np.int64))
    details: dict = {"shortlist": int(rows.size)}
    if rows.size == 0:
        return ScheduleResult((), "slots:none", "no_candidates", None, time.perf_counter() - t_wall, details)
    from ..blocks.schedule import shortlist_footprints

    weight = problem.prob if pixel_weight is None else np.asarray(pixel_weight, float)
    cells = merge_cells(shortlist_footprints(problem.footprints, rows), weight)
    grids = slot_portfolio(problem, rows)
    field_of_row = {int(problem.field_ids[r]): f for f, r in enumerate(rows)}
    start_f = {field_of_row[fid]: t for fid, t in start_first.items() if fid in field_of_row}
    details.update(n_cells=cells.n_cells, n_pixels=cells.n_pixels, grids=[])
    solutions, interrupted = _solve_grids(problem, rows, cells, grids, start_f, budget, t_budget, backend,
                                          should_stop, pair_weight, details["grids"])
    if not solutions:
        return ScheduleResult((), "slots:none", "interrupted" if interrupted else "no_solution", None,
                              time.perf_counter() - t_wall, details)
    best = _best_executable(problem, solutions, weight)
    _, obs, dropped, n_tsp, sol = best
    res = sol.result
    status = "interrupted" if interrupted else ("optimal" if all(
        s.result.status == "optimal" for s in solutions) and len(solutions) == len(grids) else res.status)
    if dropped:
        log.info("slots: dropped %d field(s) that real slews pushed out of their windows", len(dropped))
    details.update(objective=res.objective, start_objective=sol.start_objective, tsp_blocks=n_tsp,
                   backend=res.backend, backend_note=res.note, model_size=sol.model.milp.size(),
                   n_blocks=len({o.block for o in obs}))
    return ScheduleResult(tuple(obs), f"slots:{res.backend}", status, res.gap, time.perf_counter() - t_wall,
                          details, mip_bound=res.bound, dropped_by_slews=tuple(dropped),
                          grid=sol.model.instance.grid.name)


def _solve_grids(problem: PlanningProblem, rows: np.ndarray, cells, grids: list[SlotGrid],
                 start_f: dict[int, float], budget: float, t_budget: tuple, backend: str,
                 should_stop: StopCheck | None, pair_weight, runs: list[dict]) -> tuple[list[GridSolution], bool]:
    """Solve the grids in turn within the budget (from the clock's mark ``t_budget``); (the solutions found,
    interrupted), one run record each."""
    cfg = problem.config
    solutions: list[GridSolution] = []
    interrupted = False
    for i, grid in enumerate(grids):
        left = budget - problem.clock.since(t_budget)
        if left < MIN_SOLVE_S or (should_stop is not None and should_stop()):
            interrupted = interrupted or (should_stop is not None and should_stop())
            break
        inst = slot_instance(problem, rows, grid, cells=cells)
        if inst.n_pairs == 0:
            continue
        problem.clock.step("grid", inst.n_pairs)  # (A3)
        pw = None if pair_weight is None else pair_weight(problem, inst)
        model = build_slot_model(inst, cfg.penalty, pw)
        x0 = None
        start_obj = None
        if start_f:
            pairs = map_start(inst, start_f)
            if pairs.size:
                x0 = start_vector(model, pairs)
                start_obj = float(model.milp.c @ x0)
        # a share of what is left: on a quiet machine most grids solve to optimality early and
        # leave time for the rest; on a busy one the first grids still get a real chance
        share = left / min(len(grids) - i, PORTFOLIO_SPLIT)
        res = solve_milp(model.milp, backend, share, cfg.mip_gap, cfg.threads,
                         should_stop, start=x0, clock=problem.clock)
        runs.append({"grid": grid.name, "pairs": inst.n_pairs, "slots": grid.n_slots,
                     "status": res.status, "objective": res.objective, "bound": res.bound,
                     "start_objective": start_obj, "runtime_s": round(res.runtime_s, 3)})
        if res.status == "interrupted":
            interrupted = True
        if res.has_solution:
            solutions.append(GridSolution(model, res, start_obj))
        if interrupted:
            break
    return solutions, interrupted


def _best_executable(problem: PlanningProblem, solutions: list[GridSolution], weight: np.ndarray
                     ) -> tuple[float, list[Observation], list[int], int, GridSolution]:
    """The best plan after post-processing: (score, observations, dropped, TSP blocks, its solution).

    Solutions are post-processed in decreasing objective until no unprocessed
    one could do better (the cell term of a solution bounds what its
    post-processed plan covers).
    """
    def cell_term(sol: GridSolution) -> float:
        return float(sol.model.instance.cells.weight @ sol.result.x[sol.model.off_y:])

    solutions = sorted(solutions, key=lambda s: -cell_term(s))
    best = None
    for sol in solutions:
        if best is not None and best[0] >= cell_term(sol) - 1e-12:
            break
        obs, dropped, n_tsp = time_slot_plan(problem, sol.model, sol.result.x)
        score = problem.footprints.coverage({o.field_id for o in obs}, weight)
        if best is None or score > best[0] + 1e-12:
            best = (score, obs, dropped, n_tsp, sol)
    assert best is not None
    return best
