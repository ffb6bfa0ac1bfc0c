"""One slice of the large-neighbourhood search (H1-H5 of ``docs/design/milp.md``, section 6).

A slice is one interval of the night or two.  Its free fields (every
exposure inside it) and the unplanned fields worth adding (H1, H3) are
re-solved with the continuous-time model (:mod:`.continuous`, H4) while the
fixed neighbours keep their times (H2); the new whole plan replaces the
incumbent only when it covers more and keeps every timing rule
(:func:`plan_rule_problems`, H5).  The search over slices is :mod:`.lns`.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import Sequence

import numpy as np

from ...plan.document import Observation
from ...problem import PlanningProblem, StopCheck
from ...sky.footprints import Footprints
from ...sky.windows import Windows
from ...telescope.slew import overhead_time
from ..blocks.schedule import shortlist_footprints
from ..milp.solvers import MilpModel, solve_milp
from .continuous import ExactModel, build_exact_model, exact_data, solution_parts, start_from_plan

__all__ = ["resolve_slice", "plan_rule_problems", "slice_name", "Slice", "SLICE_GAP", "MIN_IMPROVEMENT", "RULE_TOL_S"]

log = logging.getLogger(__name__)

#: Relative gap at which a slice's solve stops.
SLICE_GAP = 1e-4
#: Least coverage gain (absolute probability) for a slice's plan to replace the incumbent (H5).
MIN_IMPROVEMENT = 1e-9
#: Time tolerance (s) of the rule check (the checker's is 1e-3 s).
RULE_TOL_S = 1e-6


def plan_rule_problems(problem: PlanningProblem, observations: Sequence[Observation]) -> list[str]:
    """The timing rules of a plan on the problem's windows: what is wrong (empty: every rule holds).

    Every exposure inside one window of its field and inside the horizon;
    consecutive exposures apart by the exposure plus the true overhead
    (slew, readout, filter change); every field in both filters, once each,
    the cadence apart.
    """
    cfg = problem.config
    obs = sorted(observations, key=lambda o: o.start)
    bad: list[str] = []
    for o in obs:
        if o.start < -RULE_TOL_S or o.start + o.exposure_s > problem.horizon_s + RULE_TOL_S:
            bad.append(f"horizon {o.field_id} {o.filter} {o.start:.3f}")
        elif not problem.windows.contains(o.field_id, o.start + RULE_TOL_S, o.start + o.exposure_s - RULE_TOL_S):
            bad.append(f"window {o.field_id} {o.filter} {o.start:.3f}")
    for a, b in zip(obs[:-1], obs[1:]):
        need = float(overhead_time(a.ra, a.dec, b.ra, b.dec, cfg.slew,
                                   cfg.filter_change_s if a.filter != b.filter else 0.0))
        if b.start < a.start + a.exposure_s + need - RULE_TOL_S:
            bad.append(f"overhead {a.field_id} -> {b.field_id} at {b.start:.3f}")
    starts: dict[int, list[Observation]] = {}
    for o in obs:
        starts.setdefault(o.field_id, []).append(o)
    for fid, os_ in starts.items():
        if sorted(o.filter for o in os_) != sorted(cfg.filters):
            bad.append(f"filters {fid}")
        elif abs(os_[0].start - os_[1].start) < cfg.cadence_s - RULE_TOL_S:
            bad.append(f"cadence {fid}")
    return bad


Slice = tuple[tuple[float, float], ...]


def slice_name(intervals: Slice) -> str:
    """A slice as its intervals (s), for the log."""
    return " + ".join(f"[{a:.0f}, {b:.0f}]" for a, b in intervals)


def _earliest_times(sub: PlanningProblem, model, x: np.ndarray, fixed: np.ndarray) -> dict[int, float]:
    """Exposure -> start: fixed exposures keep theirs, free ones start as early as the solution's order allows."""
    data, cfg = model.data, sub.config
    chosen, t, win = solution_parts(model, x)
    exposures = sorted((2 * f + p for f in chosen for p in (0, 1)), key=lambda e: (t[e], e))
    out: dict[int, float] = {}
    first_at: dict[int, float] = {}
    prev, free_at = None, -math.inf
    for e in exposures:
        f = e // 2
        if fixed[f]:
            start = float(t[e])
        else:
            a, _ = win.get(e, data.windows[f][0])
            start = max(a, free_at + (0.0 if prev is None else float(data.overhead[prev, e])))
            if f in first_at:
                start = max(start, first_at[f] + cfg.cadence_s)
        first_at.setdefault(f, start)
        out[e] = start
        prev, free_at = e, start + cfg.exposure_s
    return out


def _inside(t: float, exp: float, intervals: tuple[tuple[float, float], ...]) -> bool:
    """True when the exposure ``[t, t + exp]`` lies in one of the slice's intervals."""
    return any(a <= t and t + exp <= b for a, b in intervals)


def _slice_fields(pairs: dict[int, list[Observation]], intervals: tuple[tuple[float, float], ...],
                  exp: float) -> tuple[list[int], list[int], list[int]]:
    """(H1, H2) The slice's free fields (every exposure inside it), the fixed ones, and the fixed ones a free one may meet."""
    free_ids = [fid for fid, os_ in pairs.items() if all(_inside(o.start, exp, intervals) for o in os_)]
    free_set = set(free_ids)
    fixed_ids = [fid for fid in pairs if fid not in free_set]
    fixed_obs = sorted((o for fid in fixed_ids for o in pairs[fid]), key=lambda o: o.start)
    starts = np.array([o.start for o in fixed_obs])
    # (H2) the fixed exposures a free one may meet: per interval, from the last one starting before A to
    # the first one starting after B - exp
    near: set[int] = set()
    for a_s, b_s in intervals:
        before = np.flatnonzero(starts < a_s)
        after = np.flatnonzero(starts > b_s - exp)
        i0 = int(before[-1]) if before.size else 0
        i1 = int(after[0]) if after.size else len(fixed_obs) - 1
        near.update(int(o.field_id) for o in fixed_obs[i0:i1 + 1])
    return free_ids, fixed_ids, sorted(near)


def probability_in_rows(fp: Footprints, prob: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Probability ``prob`` inside each of the footprint rows ``rows`` (each row on its own; any order).

    Parameters
    ----------
    fp : Footprints
        Fields' pixel lists.
    prob : numpy.ndarray
        Weight per pixel (NESTED, ``fp.nside``).
    rows : numpy.ndarray
        Row numbers of ``fp`` (int).

    Returns
    -------
    numpy.ndarray
        (len(rows),) summed weight.
    """
    return fp.field_probability(prob)[np.asarray(rows, np.int64)]


def _slice_candidates(problem: PlanningProblem, pairs: dict[int, list[Observation]],
                      intervals: tuple[tuple[float, float], ...], fixed_ids: list[int], row_of: dict[int, int],
                      pool: np.ndarray, pool_ok: np.ndarray, n_new: int) -> tuple[np.ndarray, np.ndarray]:
    """(H3, H4) The probability the fixed fields leave uncovered, and the rows of at most ``n_new`` new fields.

    The new fields are unplanned fields of the pool whose windows inside the
    slice span a pair, by the probability they would add, most first.
    """
    cfg = problem.config
    exp = cfg.exposure_s
    # (H4) objective weights: the probability the fixed fields leave uncovered
    fp = problem.footprints
    prob = np.asarray(problem.prob, float).copy()
    fixed_rows = np.array([row_of[f] for f in fixed_ids], np.int64)
    if fixed_rows.size:
        prob[fp.union(fp.field_ids[fixed_rows])] = 0.0
    # (H3) candidates: unplanned fields whose windows inside the slice span a pair, by probability left
    w = problem.windows
    w_row = np.array([row_of.get(int(f), -1) for f in w.field_ids], np.int64)
    first = np.full(len(problem.field_ids), np.inf)
    last = np.full(len(problem.field_ids), -np.inf)
    for a_s, b_s in intervals:
        lo_c, hi_c = np.maximum(w.start, a_s), np.minimum(w.end, b_s)
        ok = (hi_c - lo_c >= exp) & (w_row >= 0)
        np.minimum.at(first, w_row[ok], lo_c[ok])
        np.maximum.at(last, w_row[ok], hi_c[ok])
    fits = last - first >= cfg.cadence_s + exp
    planned = np.isin(problem.field_ids[pool], np.fromiter(pairs, np.int64, len(pairs)))
    cand = pool[pool_ok & ~planned & fits[pool]]
    if cand.size and n_new > 0:
        gain = probability_in_rows(fp, prob, cand)
        keep = np.argsort(-gain, kind="stable")[:n_new]
        cand = cand[keep][gain[keep] > 0.0]
    else:
        cand = cand[:0]
    return prob, cand


def _slice_problem(problem: PlanningProblem, prob: np.ndarray, rows: np.ndarray, n_fixed: int,
                   intervals: tuple[tuple[float, float], ...]) -> PlanningProblem:
    """(H4) The slice's problem on ``rows`` (the fixed neighbours first): weights ``prob``, windows as (H1) clips them."""
    exp = problem.config.exposure_s
    w = problem.windows
    # (H1) the free fields' windows clipped to the slice's intervals, the fixed ones' kept
    ws_id, ws_a, ws_b = [], [], []
    for k, r in enumerate(rows):
        fid = int(problem.field_ids[r])
        for a0, b0 in w.for_field(fid):
            pieces = [(a0, b0)] if k < n_fixed else [(max(a0, a_s), min(b0, b_s)) for a_s, b_s in intervals]
            for a, b in pieces:
                if b - a >= exp:
                    ws_id.append(fid)
                    ws_a.append(a)
                    ws_b.append(b)
    return dataclasses.replace(problem, prob=prob, field_ids=problem.field_ids[rows], ra=problem.ra[rows],
                               dec=problem.dec[rows], footprints=shortlist_footprints(problem.footprints, rows),
                               windows=Windows(np.asarray(ws_id, np.int64), np.asarray(ws_a), np.asarray(ws_b)))


def _pin_neighbours(model: ExactModel, x0: np.ndarray, near_ids: list[int], pairs: dict[int, list[Observation]],
                    filters: tuple[str, ...]) -> MilpModel:
    """(H2) The slice's model with its fixed neighbours pinned: observed, at their times, in their filter order."""
    milp = model.milp
    col_lo, col_hi = milp.col_lo.copy(), milp.col_hi.copy()
    phi = {filters[0]: 0, filters[1]: 1}
    for f, fid in enumerate(near_ids):  # (H2) fixed: observed, at their times, in their filter order
        col_lo[f] = col_hi[f] = 1.0
        col_lo[model.off_d + f] = col_hi[model.off_d + f] = x0[model.off_d + f]
        for o in pairs[fid]:
            e = model.off_t + 2 * f + phi[o.filter]
            col_lo[e] = col_hi[e] = x0[e]
    return dataclasses.replace(milp, col_lo=col_lo, col_hi=col_hi)


def _new_observations(problem: PlanningProblem, sub: PlanningProblem, model: ExactModel, x: np.ndarray, rows: np.ndarray,
                      n_fixed: int, n_fields: int, observations: Sequence[Observation]) -> list[Observation]:
    """The slice's new exposures at their earliest times, each in the block of the plan's exposure before it."""
    cfg = problem.config
    fixed_mask = np.zeros(n_fields, bool)
    fixed_mask[:n_fixed] = True
    times = _earliest_times(sub, model, x, fixed_mask)
    block_after = sorted(((o.start, o.block) for o in observations))
    new_obs: list[Observation] = []
    for e, start in times.items():
        f = e // 2
        if f < n_fixed:
            continue
        r = rows[f]
        blocks = [b for s, b in block_after if s <= start]
        new_obs.append(Observation(int(problem.field_ids[r]), float(problem.ra[r]), float(problem.dec[r]),
                                   cfg.filters[e % 2], float(start), cfg.exposure_s, blocks[-1] if blocks else 0))
    return new_obs


def resolve_slice(problem: PlanningProblem, observations: Sequence[Observation], pairs: dict[int, list[Observation]],
                   intervals: tuple[tuple[float, float], ...], row_of: dict[int, int], pool: np.ndarray,
                   pool_ok: np.ndarray, time_limit_s: float, should_stop: StopCheck | None,
                   max_free: int) -> list[Observation] | None:
    """One slice's re-solve: the new whole plan when it covers strictly more and keeps every rule, else None.

    ``observations`` is the incumbent plan, ``pairs`` its exposures by field.

    A slice is one interval of the night or two (a field's two filters may lie hours apart, e.g. at
    the end of one night and the start of the next: the cadence is a least separation).
    """
    cfg = problem.config
    exp = cfg.exposure_s
    free_ids, fixed_ids, near_ids = _slice_fields(pairs, intervals, exp)
    prob, cand = _slice_candidates(problem, pairs, intervals, fixed_ids, row_of, pool, pool_ok,
                                   max_free - len(free_ids))
    free_rows = np.array([row_of[f] for f in free_ids], np.int64)
    if free_rows.size + cand.size == 0:
        return None
    near_rows = np.array([row_of[f] for f in near_ids], np.int64)
    rows = np.concatenate([near_rows, free_rows, cand]).astype(np.int64)
    n_fixed = near_rows.size
    sub = _slice_problem(problem, prob, rows, n_fixed, intervals)
    data = exact_data(sub)
    if n_fixed and not data.pairable[:n_fixed].all():
        return None
    if data.overhead.size and float(data.overhead.max()) > exp:
        return None  # the pairwise model is exact only when an exposure outlasts every overhead
    model = build_exact_model(sub, data)
    problem.clock.step("slice", model.milp.A.nnz)  # (A3) the slice's model, its times and its rule check
    sub_obs = [o for f in near_ids + free_ids for o in pairs[f]]
    x0 = start_from_plan(model, sub, sub_obs)
    if x0 is None:
        return None
    milp = _pin_neighbours(model, x0, near_ids, pairs, cfg.filters)
    start_obj = float(milp.c @ x0)
    # (V6) a slice that cannot add min_gain to the coverage stops once its bound proves it
    res = solve_milp(milp, "highs", time_limit_s, SLICE_GAP, cfg.threads, should_stop, start=x0, abs_gap=cfg.min_gain,
                     clock=problem.clock)
    if res.x is None or res.objective is None or res.objective <= start_obj + MIN_IMPROVEMENT:
        return None
    new_obs = _new_observations(problem, sub, model, res.x, rows, n_fixed, data.n_fields, observations)
    plan = sorted([o for fid in fixed_ids for o in pairs[fid]] + new_obs, key=lambda o: o.start)
    bad = plan_rule_problems(problem, plan)
    if bad:
        log.info("lns: slice %s rejected: %s", slice_name(intervals), bad[0])
        return None
    return plan
