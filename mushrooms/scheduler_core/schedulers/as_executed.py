"""What of a plan's coverage survives ZTF's execution of its queues (the plan's ``coverage_as_executed``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Iterable, Sequence

import numpy as np

from ..config import ONE_NIGHT_PAIR_S
from ..executed import MIN_PROCESSED_FRACTION, ExecutedExposure, is_done
from ..sequences import covered_fields, sequence_progress
from ..telescope.executor import execute_queues, executed_exposures, queue_set_from_payloads
from ..telescope.timing import TelescopeTiming

if TYPE_CHECKING:
    from ..plan.document import Plan
    from ..sky.footprints import Footprints

__all__ = ["cadence_coverage", "sequence_coverage", "planned_sequence_coverage", "execute_plan_queues",
           "queue_coverage", "queue_coverages", "keyed_coverage_as_executed", "keyed_coverages_as_executed",
           "execution_key", "AS_EXECUTED_MEMO"]

#: ``ScheduleResult.details`` key of the executed coverages already computed: :func:`execution_key` -> value.
AS_EXECUTED_MEMO = "coverage_as_executed_memo"


def cadence_coverage(executed: Iterable[ExecutedExposure], footprints: "Footprints", prob: np.ndarray,
                     filters: tuple[str, ...] = ("g", "r"), cadence_s: float = 0.0, require: str = "both",
                     min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> float:
    """Probability inside the covered fields (Q14): done in both filters at least ``cadence_s`` apart (E3).

    ``filters`` is the plan's sequence: a field is covered by the first two
    (F1, whatever its later visits did), or one exposure of a one-filter
    sequence.  ``require="any"`` counts a field once one done exposure
    exists in any of the filters.
    """
    if require not in ("both", "any"):
        raise ValueError(f"require must be 'both' or 'any', got {require!r}")
    executed = list(executed)
    ids = covered_fields(executed, filters, min_processed_fraction, cadence_s)
    if require == "any":
        ids |= {int(e.field_id) for e in executed if e.filter in filters and is_done(e, min_processed_fraction)}
    missing = sorted(ids - {int(f) for f in footprints.field_ids})
    if missing:
        raise ValueError(f"field(s) {missing[:5]} not in the footprints")
    return float(footprints.coverage(sorted(ids), prob)) if ids else 0.0


def sequence_coverage(executed: Iterable[ExecutedExposure], footprints: "Footprints", prob: np.ndarray,
                      filters: tuple[str, ...] = ("g", "r"), cadence_s: float = 0.0,
                      max_separation_s: float = math.inf,
                      min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> float:
    """Probability inside the fields whose whole sequence is done (F2: ``n = k``; Q21).

    Each visit counted at least ``cadence_s`` after the previous counted one
    and at most ``max_separation_s`` after the first; for a pair (or one
    filter) the fields :func:`cadence_coverage` counts, within the separation.
    """
    progress = sequence_progress(executed, filters, min_processed_fraction, cadence_s, max_separation_s)
    ids = sorted(f for f, p in progress.items() if p.done >= len(tuple(filters)))
    missing = sorted(set(ids) - {int(f) for f in footprints.field_ids})
    if missing:
        raise ValueError(f"field(s) {missing[:5]} not in the footprints")
    return float(footprints.coverage(ids, prob)) if ids else 0.0


def planned_sequence_coverage(executed: Iterable[ExecutedExposure], observations: Iterable[Any],
                              footprints: "Footprints", prob: np.ndarray, filters: tuple[str, ...],
                              cadence_s: float = 0.0, max_separation_s: float = math.inf,
                              min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> float:
    """Probability inside the fields whose every planned visit is done (F2: ``n`` at least the visits the plan
    gives the field, its whole sequence or its cut one, F10).

    Q21 (:func:`sequence_coverage`) for a plan without cut sequences; a field
    F10 cut to its g and r counts once they are done, as F1 credits it.
    """
    seq = tuple(filters)
    planned: dict[int, int] = {}
    for o in observations:
        if o.filter in seq:
            planned[int(o.field_id)] = planned.get(int(o.field_id), 0) + 1
    progress = sequence_progress(executed, seq, min_processed_fraction, cadence_s, max_separation_s)
    ids = sorted(f for f, p in progress.items() if p.done >= min(planned.get(f, len(seq)), len(seq)))
    return float(footprints.coverage(ids, prob)) if ids else 0.0


def execute_plan_queues(plan: "Plan", queues: Sequence[dict[str, Any]] | None = None, late_s: float = 0.0,
                        timing: TelescopeTiming = TelescopeTiming(),
                        closures_s: Sequence[tuple[float, float]] = ()) -> tuple[ExecutedExposure, ...]:
    """ZTF's execution of a plan's queues (default :func:`~..plan.exports.to_trigger_queues`), from its first observation.

    Parameters
    ----------
    plan : Plan
        The plan (its start is the epoch; the run ends at its end).
    queues : sequence of dict, optional
        The payloads submitted, in submission order.
    late_s : float
        The telescope is free this long (s) after the plan's first observation.
    timing : TelescopeTiming
        The telescope.
    closures_s : sequence of (float, float)
        Dome closures (s since the plan's start).
    """
    from ..plan.exports import timed_queue_set

    if not plan.observations:
        return ()
    # on time at the modelled speed the closes are never reached (Q18): the cheaper wide ones give the same run
    nominal = late_s == 0 and not closures_s and timing == TelescopeTiming()
    payloads, sky = timed_queue_set(plan, robust=not nominal) if queues is None else (queues, None)
    qs = queue_set_from_payloads(payloads, plan.start, timing)
    start = plan.observations[0].start + late_s
    done = execute_queues(qs, plan.start, start, float((plan.end - plan.start).to_value("s")), timing,
                          closures_s=closures_s, sky=sky if sky is not None and sky.serves(start, timing) else None)
    return executed_exposures(qs, done, plan.start)


def queue_coverage(plan: "Plan", footprints: "Footprints", prob: np.ndarray,
                   queues: Sequence[dict[str, Any]] | None = None, late_s: float = 0.0,
                   timing: TelescopeTiming = TelescopeTiming()) -> float:
    """Cadence-valid coverage of a plan's queues as ZTF executes them (Q14): ``metrics.coverage_as_executed``.

    The plan's own filter sequence and cadence (its ``config``) decide what
    covers a field (F1).
    """
    return queue_coverages(plan, footprints, prob, queues, late_s, timing, sequence=False)[0]


def queue_coverages(plan: "Plan", footprints: "Footprints", prob: np.ndarray,
                    queues: Sequence[dict[str, Any]] | None = None, late_s: float = 0.0,
                    timing: TelescopeTiming = TelescopeTiming(), sequence: bool = True) -> tuple[float, float | None]:
    """One run of a plan's queues, two scores: ``coverage_as_executed`` (Q14) and ``sequence_coverage_as_executed`` (Q21).

    The second is the probability inside the fields whose every visit of the
    plan's sequence is executed (F2, each a cadence after the previous one,
    the last within the pair separation ``M`` of the first); for a pair or a
    single filter it is the first.  ``sequence=False`` skips it (None).
    """
    config = plan.config or {}
    filters = tuple(config.get("filters", ("g", "r")))
    cadence_s = float(config.get("cadence_s", 1800.0))
    executed = execute_plan_queues(plan, queues, late_s, timing)
    pair = cadence_coverage(executed, footprints, prob, filters, cadence_s)  # type: ignore[arg-type]
    if not sequence:
        return pair, None
    if len(filters) <= 2:
        return pair, pair
    separation = float(config.get("pair_max_s") or 0.0) or ONE_NIGHT_PAIR_S
    return pair, sequence_coverage(executed, footprints, prob, filters, cadence_s, separation)  # type: ignore[arg-type]


def execution_key(problem: Any, observations: Sequence[Any]) -> tuple:
    """What the executor's run of a plan depends on: start, horizon, cadence, filters and each exposure.

    Two plans with one key have one ``coverage_as_executed`` (the queues are
    made from these, :func:`~..plan.exports.timed_queue_set`).
    """
    config = problem.config
    return (float(problem.start.mjd), float(config.horizon_s), float(config.cadence_s), tuple(config.filters),
            tuple((int(o.field_id), o.filter, float(o.start), float(o.exposure_s), float(o.ra), float(o.dec))
                  for o in observations))


def keyed_coverage_as_executed(problem: Any, result: Any, memo: dict[tuple, float] | None = None
                               ) -> tuple[tuple | None, float]:
    """A scheduler result's ``coverage_as_executed`` as its published plan will have it (after the least-gain rule).

    Parameters
    ----------
    problem : PlanningProblem
        The problem solved (start, horizon, cadence, footprints, probabilities).
    result : ScheduleResult
        A candidate schedule; a value remembered in its ``details``
        (:data:`AS_EXECUTED_MEMO`) for the same plan is returned as is.
    memo : dict, optional
        More remembered values (:func:`execution_key` -> coverage), e.g. of
        other candidates with the same plan.

    Returns
    -------
    (tuple or None, float)
        The plan's :func:`execution_key` (None for an empty plan) and its executed coverage.
    """
    key, pair, _ = _keyed(problem, result, memo, sequence=False)
    return key, pair


def keyed_coverages_as_executed(problem: Any, result: Any, memo: dict[tuple, float] | None = None
                                ) -> tuple[tuple | None, float, float]:
    """:func:`keyed_coverage_as_executed` and, from the same run, :func:`planned_sequence_coverage` (Q15 of a
    sequence of three or more: what the hybrid's choice weighs first); for a pair the second is the first.

    The second is remembered in ``memo`` under the key with ``"sequence"`` appended.
    """
    return _keyed(problem, result, memo, sequence=len(tuple(problem.config.filters)) > 2)


def _keyed(problem: Any, result: Any, memo: dict[tuple, float] | None, sequence: bool
           ) -> tuple[tuple | None, float, float]:
    """(key, pair coverage as executed, coverage of the sequences done as planned) of a candidate."""
    from astropy.time import TimeDelta

    from ..plan.document import EventInfo, Plan, PlanMetrics, sorted_observations
    from .gain import drop_low_gain

    config = problem.config
    kept = drop_low_gain(result, problem.footprints, problem.prob, config.min_gain)
    if not kept.observations:
        return None, 0.0, 0.0
    observations = sorted_observations(kept.observations)
    key = execution_key(problem, observations)
    known = {**(result.details or {}).get(AS_EXECUTED_MEMO, {}), **(memo or {})}
    if key in known and (not sequence or key + ("sequence",) in known):
        pair = float(known[key])
        return key, pair, float(known[key + ("sequence",)]) if sequence else pair
    if config.telescope != "ztf":  # the executor model is ZTF's queue (ztf_too): another telescope's plan as planned
        planned = problem.footprints.coverage({o.field_id for o in observations}, problem.prob)
        return key, planned, planned
    clock = getattr(problem, "clock", None)
    if clock is not None:
        clock.step("execute", len(observations))  # (A3) the executor's run, on the budget of the stage asking
    plan = Plan(plan_id="candidate", start=problem.start,
                end=problem.start + TimeDelta(config.horizon_s, format="sec"), observations=observations,
                metrics=PlanMetrics(coverage=0.0, solver="", status="", mip_gap=None, runtime_s=0.0, n_fields=0,
                                    n_exposures=len(observations)),
                event=EventInfo(), config={"cadence_s": config.cadence_s, "filters": list(config.filters)})
    if not sequence:
        pair = queue_coverage(plan, problem.footprints, problem.prob)
        return key, pair, pair
    executed = execute_plan_queues(plan)
    filters = tuple(config.filters)
    pair = cadence_coverage(executed, problem.footprints, problem.prob, filters, config.cadence_s)
    whole = planned_sequence_coverage(executed, observations, problem.footprints, problem.prob, filters,
                                      config.cadence_s, config.pair_separation_s)
    if memo is not None:
        memo[key + ("sequence",)] = whole
    return key, pair, whole
