"""Large-neighbourhood search: re-solve time slices of an incumbent plan exactly.

The slot grids (:mod:`..slots.schedule`) are one restricted family of plans:
a pair placed at the very edge of a short window, or blocks that do not
line up with when fields rise and set, cannot be expressed.  This stage
takes the best plan so far and repeatedly

1. picks a slice of the night: one interval ``[A, B]`` (:data:`SLICE_S`
   long; those where the incumbent idles most first, every half interval)
   or two (a field's filters may be hours apart, e.g. across the day on a
   24 h horizon: each interval with the one sharing the most visible
   probability);
2. frees the incumbent's fields whose two exposures both lie inside it,
   keeps every other exposure where it is (a field whose pair straddles a
   slice boundary stays fixed, both exposures), and adds the unplanned
   fields that can hold a pair inside the slice with the largest
   probability not already covered by the fixed fields;
3. solves the continuous-time model (:mod:`.continuous`, C0–C6) of the
   free fields, their windows clipped to the slice, together with the fixed
   exposures the free ones may meet (variables fixed at their times), the
   objective being the probability the fixed fields leave uncovered
   (``docs/design/milp.md`` section 6, H1–H5);
4. keeps the new plan only when every rule holds (windows, overheads,
   cadence, both filters, checked again on the whole plan) and it covers
   strictly more (H5): the incumbent is never worse.

It stops when the budget ends, ``should_stop`` says so, the plan is
within ``min_gain`` of the certified bound (``enough``), or a whole round
of slices or :data:`MAX_IDLE_S` seconds bring nothing (a slice's solve
never runs past that idle stop, and stops as soon as its bound proves it
cannot add ``min_gain``).  A slice's plan replaces the incumbent only when
ZTF's scheduler executes it no worse (H5, :mod:`..as_executed`):
a plan packed to the cadence and the night's end loses what the executor's
later start of each pass pushes out of the night.

Steps 2-4 for one slice are :func:`~.lns_slice.resolve_slice`; here, the search over slices.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...sequences import require_pair
from ...plan.document import Observation
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from .lns_slice import MIN_IMPROVEMENT, Slice, plan_rule_problems, resolve_slice, slice_name
from ..gain import published_coverage

__all__ = ["lns_improve", "plan_rule_problems", "SLICE_S", "MAX_FREE_FIELDS", "SLICE_LIMIT_S", "MIN_SLICE_S",
           "MAX_IDLE_S"]

log = logging.getLogger(__name__)

#: Length (s) of a re-solved slice of the night.
SLICE_S = 4500.0
#: Most fields (incumbent's and new) free in one slice.
MAX_FREE_FIELDS = 22
#: Time limit (s) of one slice's solve (less when the budget left is shorter).
SLICE_LIMIT_S = 2.0
#: No slice is started with less than this (s) of the budget left.
MIN_SLICE_S = 0.3
#: The search stops after a whole round of slices without a gain, or after this long (s) without one.  A count
#: of slices is no stop: on a reduced bns_o3/11 the gains come after 8 quick slices without one.  Measured on
#: the 51 shared maps the LNS runs on (``benchmarks/quality/lns_idle_replay.py`` on a run to the budget,
#: ``lns_idle_*`` in benchmarks/results): it gains +0.0012 coverage on average run to the end of its budget;
#: a 5 s stop keeps all but 0.00012 of that in a median 7.1 s, 3 s all but 0.0005 in 5.1 s, 2 s all but
#: 0.00076 in 4.1 s, 1 s all but 0.0008 in 3.1 s.  1 s: waiting 3 s instead gains 0.0003 on average, less than
#: the least gain a field must bring (``min_gain`` 0.001), for 2 s of every plan (the optimiser stops when its
#: stages cannot improve the plan by more than that; ``docs/design/milp.md`` V6).
MAX_IDLE_S = 1.0


@dataclass
class _State:
    """The incumbent: its observations and what they cover (as published, after the least-gain rule; raw; as
    ZTF's scheduler executes its queues, Q14)."""

    observations: list[Observation]
    published: float
    coverage: float
    executed: float

    def beaten_by(self, other: "_State") -> bool:
        """(H5) ``other`` executes no worse, and publishes more, or as much (within :data:`MIN_IMPROVEMENT`)
        and covers more raw."""
        if other.executed < self.executed - MIN_IMPROVEMENT:
            return False
        if other.published > self.published + MIN_IMPROVEMENT:
            return True
        return other.published >= self.published - MIN_IMPROVEMENT and other.coverage > self.coverage + MIN_IMPROVEMENT


def _state(problem: PlanningProblem, observations: Sequence[Observation], memo: dict[tuple, float]) -> _State:
    """The state of a plan; ``memo`` (:func:`~..as_executed.execution_key` -> executed coverage) is filled."""
    from ..as_executed import keyed_coverage_as_executed

    obs = sorted(observations, key=lambda o: o.start)
    res = ScheduleResult(tuple(obs), "lns", "", None, 0.0)
    key, executed = keyed_coverage_as_executed(problem, res, memo)
    if key is not None:
        memo[key] = executed
    return _State(obs, published_coverage(problem, res),
                  problem.footprints.coverage({o.field_id for o in obs}, problem.prob), executed)


def _pairs_of(problem: PlanningProblem, observations: Sequence[Observation]) -> dict[int, list[Observation]] | None:
    """Field ID -> its two exposures (one per filter), or None when the plan is not of that shape."""
    cfg = problem.config
    by: dict[int, list[Observation]] = {}
    for o in observations:
        by.setdefault(int(o.field_id), []).append(o)
    for os_ in by.values():
        if sorted(o.filter for o in os_) != sorted(cfg.filters) or any(o.exposure_s != cfg.exposure_s for o in os_):
            return None
    return by


def _slices(problem: PlanningProblem, state: _State, lo: float, hi: float, length: float,
            field_prob: np.ndarray) -> list[Slice]:
    """The slices of a round: single intervals and pairs of intervals, alternating.

    Single: ``[lo, hi]`` cut in intervals of ``length`` (s) every half length, those where the
    incumbent idles most first (only those where a field is visible).  Pairs: each interval with the
    one not overlapping it that shares the most probability of fields visible in both (a pair of
    exposures split between them), most shared first.
    """
    if hi - lo <= length:
        return [((lo, hi),)]
    starts = np.arange(lo, hi - length + 1e-9, length / 2.0)
    if starts[-1] < hi - length - 1e-9:
        starts = np.append(starts, hi - length)
    busy = np.zeros(starts.size)
    for o in state.observations:
        a, b = o.start, o.start + o.exposure_s
        busy += np.clip(np.minimum(b, starts + length) - np.maximum(a, starts), 0.0, None)
    w = problem.windows
    exp = problem.config.exposure_s
    rows = np.searchsorted(problem.field_ids, w.field_ids, sorter=np.argsort(problem.field_ids))
    rows = np.argsort(problem.field_ids)[np.clip(rows, 0, len(problem.field_ids) - 1)]
    vis = np.zeros((starts.size, len(problem.field_ids)), bool)
    for k, a in enumerate(starts):
        ok = np.minimum(w.end, a + length) - np.maximum(w.start, a) >= exp
        vis[k, rows[ok]] = True
    seen = vis.any(axis=1)
    order = [int(i) for i in np.argsort(busy, kind="stable") if seen[i]]  # idle first
    singles: list[Slice] = [((float(starts[i]), float(starts[i] + length)),) for i in order]
    shared = (vis.astype(float) * field_prob) @ vis.T.astype(float)
    apart = np.abs(starts[:, None] - starts[None, :]) >= length
    shared = np.where(apart, shared, 0.0)
    pairs: dict[tuple[int, int], float] = {}
    for i in range(starts.size):
        j = int(np.argmax(shared[i]))
        if shared[i, j] > 0.0:
            pairs[(min(i, j), max(i, j))] = float(shared[i, j])
    ranked = sorted(pairs, key=lambda ij: -pairs[ij])
    doubles: list[Slice] = [((float(starts[i]), float(starts[i] + length)),
                             (float(starts[j]), float(starts[j] + length))) for i, j in ranked]
    out: list[Slice] = []  # interleaved: a round cut short by MAX_IDLE_S still tries both kinds
    for k in range(max(len(singles), len(doubles))):
        out += singles[k:k + 1] + doubles[k:k + 1]
    return out


def lns_improve(problem: PlanningProblem, seed: ScheduleResult, should_stop: StopCheck | None = None,
                time_limit_s: float | None = None, pool: np.ndarray | None = None,
                slice_s: float = SLICE_S, max_free: int = MAX_FREE_FIELDS,
                max_idle_s: float = MAX_IDLE_S, enough: float | None = None) -> ScheduleResult:
    """Improve ``seed`` by exact re-solves of slices of the night (H1–H5); never worse than the seed.

    Parameters
    ----------
    problem : PlanningProblem
        Uses ``config.exposure_s``, ``cadence_s``, ``filters``, ``slew``,
        ``filter_change_s``, ``threads`` and ``time_limit_s``.
    seed : ScheduleResult
        A rule-abiding plan, every field once per filter at ``exposure_s``
        (else it comes back unchanged, status ``unsupported_seed``).
    should_stop : callable, optional
        Polled between slices and by the solver.
    time_limit_s : float, optional
        Budget (s, on ``problem.clock``: wall or work seconds); default ``config.time_limit_s``.
    pool : numpy.ndarray, optional
        Rows of ``problem.field_ids`` the new fields come from (default all).
    slice_s : float
        Slice length (s).
    max_free : int
        Most free fields per slice.
    max_idle_s : float
        The search stops after this long (s, on the clock) without a gain.
    enough : float, optional
        The search stops once the plan covers this much (the certified
        bound less ``min_gain``: no slice can then add more than that).

    Returns
    -------
    ScheduleResult
        ``solver`` ``lns:highs``; status ``improved`` or ``no_improvement``
        (``interrupted`` when ``should_stop`` ended it); ``details`` hold the
        slices tried and accepted, the coverage of seed and result, and
        each gain's slice count (``improved_at``), time (s, ``elapsed_at``)
        and coverage (``coverage_at``).
    """
    require_pair(problem.config.filters, "LNS")
    t0, clock = time.perf_counter(), problem.clock
    start = clock.mark()
    cfg = problem.config
    budget = cfg.time_limit_s if time_limit_s is None else float(time_limit_s)
    fp = problem.footprints
    seed_cov = fp.coverage({o.field_id for o in seed.observations}, problem.prob)
    details: dict = {"seed_coverage": seed_cov, "slices_tried": 0, "slices_improved": 0, "slice_s": slice_s,
                     "improved_at": [], "elapsed_at": [], "coverage_at": []}

    def result(obs, status, cov):
        details.update(coverage=cov)
        return ScheduleResult(tuple(obs), "lns:highs", status, None, time.perf_counter() - t0, details)

    pairs = _pairs_of(problem, seed.observations)
    if pairs is None:
        return result(seed.observations, "unsupported_seed", seed_cov)
    row_of = {int(f): i for i, f in enumerate(problem.field_ids)}
    if any(f not in row_of for f in pairs):
        return result(seed.observations, "unsupported_seed", seed_cov)
    pool = np.arange(len(problem.field_ids)) if pool is None else np.asarray(pool, np.int64)
    w = problem.windows
    pool_ok = np.isin(problem.field_ids[pool], w.field_ids)
    if w.start.size == 0:
        return result(seed.observations, "no_improvement", seed_cov)
    lo = max(0.0, float(w.start.min()))
    hi = min(problem.horizon_s, float(w.end.max()))
    from ..as_executed import AS_EXECUTED_MEMO

    memo: dict[tuple, float] = dict((seed.details or {}).get(AS_EXECUTED_MEMO, {}))
    details[AS_EXECUTED_MEMO] = memo  # the executed coverage of the seed and every plan scored: the hybrid reuses it
    state = seed_state = _state(problem, seed.observations, memo)
    interrupted = False
    field_prob = fp.field_probability(problem.prob)
    slices = _slices(problem, state, lo, hi, slice_s, field_prob)
    i = since_gain = 0
    last_gain = clock.mark()
    while since_gain < len(slices):  # a whole round without a gain ends it
        left = budget - clock.since(start)  # (A1)
        if should_stop is not None and should_stop():
            interrupted = True
            break
        idle_left = max_idle_s - clock.since(last_gain)  # a slice never outlasts the idle stop
        if min(left, idle_left) < MIN_SLICE_S:
            break
        if enough is not None and state.published >= enough:
            details["stopped_at"] = "bound"
            break
        intervals = slices[i]
        i += 1
        if i == len(slices):  # a new round, the idlest slices of the incumbent first
            slices, i = _slices(problem, state, lo, hi, slice_s, field_prob), 0
        details["slices_tried"] += 1
        plan = resolve_slice(problem, state.observations, pairs, intervals, row_of, pool, pool_ok,
                              min(SLICE_LIMIT_S, left, idle_left), should_stop, max_free)
        new = _state(problem, plan, memo) if plan is not None else None
        if new is not None and state.beaten_by(new):  # (H5) strictly better only
            log.info("lns: slice %s s: coverage %.5f -> %.5f (executed %.5f -> %.5f)", slice_name(intervals),
                     state.coverage, new.coverage, state.executed, new.executed)
            state = new
            pairs = _pairs_of(problem, plan)
            details["slices_improved"] += 1
            details["improved_at"].append(details["slices_tried"])
            details["elapsed_at"].append(round(time.perf_counter() - t0, 2))
            details["coverage_at"].append(round(state.coverage, 6))
            since_gain = 0
            last_gain = clock.mark()
        else:
            if new is not None and new.executed < state.executed - MIN_IMPROVEMENT:
                log.info("lns: slice %s s: coverage %.5f -> %.5f refused: executed %.5f -> %.5f (Q14)",
                         slice_name(intervals), state.coverage, new.coverage, state.executed, new.executed)
            since_gain += 1
    status = "interrupted" if interrupted else ("improved" if state is not seed_state else "no_improvement")
    if state is seed_state:  # unchanged: the seed's own observations, in its order
        return result(seed.observations, status, seed_cov)
    return result(state.observations, status, state.coverage)
