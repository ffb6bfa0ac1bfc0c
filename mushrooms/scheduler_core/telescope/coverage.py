"""What of a plan's coverage survives ZTF's execution of its queues (the plan's ``coverage_as_executed``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable, Sequence

import numpy as np

from ..executed import MIN_PROCESSED_FRACTION, ExecutedExposure, done_pairs
from .executor import execute_queues, executed_exposures, queue_set_from_payloads
from .timing import TelescopeTiming

if TYPE_CHECKING:
    from ..plan.document import Plan
    from ..sky.footprints import Footprints

__all__ = ["cadence_coverage", "execute_plan_queues", "queue_coverage", "result_coverage_as_executed"]


def cadence_coverage(executed: Iterable[ExecutedExposure], footprints: "Footprints", prob: np.ndarray,
                     filters: tuple[str, str] = ("g", "r"), cadence_s: float = 0.0, require: str = "both",
                     min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> float:
    """Probability inside the fields done in both filters at least ``cadence_s`` apart (Q14; E3).

    ``require="any"`` counts a field once one done exposure exists in either filter.
    """
    if require not in ("both", "any"):
        raise ValueError(f"require must be 'both' or 'any', got {require!r}")
    pairs = done_pairs(executed, filters, min_processed_fraction, cadence_s)
    ids = set(pairs.both) | (set(pairs.one) if require == "any" else set())
    missing = sorted(ids - {int(f) for f in footprints.field_ids})
    if missing:
        raise ValueError(f"field(s) {missing[:5]} not in the footprints")
    return float(footprints.coverage(sorted(ids), prob)) if ids else 0.0


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

    The plan's own filters and cadence (its ``config``) decide what a pair is.
    """
    config = plan.config or {}
    filters = tuple(config.get("filters", ("g", "r")))[:2]
    cadence_s = float(config.get("cadence_s", 1800.0))
    executed = execute_plan_queues(plan, queues, late_s, timing)
    return cadence_coverage(executed, footprints, prob, filters, cadence_s)  # type: ignore[arg-type]


def result_coverage_as_executed(problem: Any, result: Any) -> float:
    """A scheduler result's ``coverage_as_executed`` as its published plan will have it (after the least-gain rule).

    Parameters
    ----------
    problem : PlanningProblem
        The problem solved (start, horizon, cadence, footprints, probabilities).
    result : ScheduleResult
        A candidate schedule.
    """
    from astropy.time import TimeDelta

    from ..plan.document import EventInfo, Plan, PlanMetrics, sorted_observations
    from ..schedulers.gain import drop_low_gain

    config = problem.config
    kept = drop_low_gain(result, problem.footprints, problem.prob, config.min_gain)
    if not kept.observations:
        return 0.0
    observations = sorted_observations(kept.observations)
    plan = Plan(plan_id="candidate", start=problem.start,
                end=problem.start + TimeDelta(config.horizon_s, format="sec"), observations=observations,
                metrics=PlanMetrics(coverage=0.0, solver="", status="", mip_gap=None, runtime_s=0.0, n_fields=0,
                                    n_exposures=len(observations)),
                event=EventInfo(), config={"cadence_s": config.cadence_s, "filters": list(config.filters)})
    return queue_coverage(plan, problem.footprints, problem.prob)
