"""Coverage at matched telescope time: what a row's executed plan had covered after another row's open-shutter time.

A row that keeps the shutter open longer is not shown to plan better by
covering more.  The matched comparison asks what the longer row had covered
when it had spent only the other row's open-shutter time: the **time-ordered
prefix** of its executed records (the queue set as ZTF's scheduler runs it,
:func:`~mushrooms.scheduler_core.schedulers.as_executed.execute_plan_queues`,
the executor of the ``coverage_executed`` column) whose summed exposure time
of done exposures (E1) does not exceed the budget, scored by the same pair
rule (:func:`~mushrooms.scheduler_core.schedulers.as_executed.cadence_coverage`:
both of the plan's first two filters done, at least the cadence apart).

The prefix is a stand-in for a planner given less time, and a conservative
one: the planner given the budget could choose the fields for it, while the
prefix keeps the fields the full plan happened to take first (ordered by
time, not by probability), so the prefix's coverage is at most what the
planner would reach with the budget, up to the planner's optimality.

:func:`executed_curve` gives, after each done exposure in time order, the
cumulative open-shutter seconds and the coverage so far (a step function);
:func:`subset_curve` the same over the covered fields taken best first (a
tighter stand-in, still a sub-schedule of what was executed);
:func:`coverage_at` reads either at a budget.  Pure functions, no I/O.
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

import numpy as np

from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, ExecutedExposure, is_done
from ..scheduler_core.schedulers.as_executed import cadence_coverage

__all__ = ["executed_curve", "subset_curve", "coverage_at", "plan_curve", "TOLERANCE_S"]

#: Open-shutter seconds a prefix may exceed its budget by (rounding of the records' sums).
TOLERANCE_S = 0.5


def executed_curve(executed: Iterable[ExecutedExposure], footprints: Any, prob: np.ndarray,
                   filters: Sequence[str] = ("g", "r"), cadence_s: float = 0.0,
                   min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> np.ndarray:
    """Cumulative open-shutter time and pair-rule coverage after each done exposure, in time order.

    Parameters
    ----------
    executed : iterable of ExecutedExposure
        What was executed (aborted and failed attempts included: they add no
        time and cover nothing).
    footprints : Footprints
        Footprints of (at least) the executed fields, at the map's resolution.
    prob : numpy.ndarray
        The sky map's probability per pixel.
    filters : sequence of str
        The plan's filter sequence (a field is covered by its first two, F1).
    cadence_s : float
        Least separation (s) of a field's two filters.
    min_processed_fraction : float
        Threshold of the done rule (E1).

    Returns
    -------
    numpy.ndarray
        Shape (n + 1, 2), n done exposures: row k is (open-shutter seconds of
        the first k done exposures, coverage of those k); row 0 is (0, 0).
        Ties in start time keep the records' order.
    """
    done = [e for e in executed if is_done(e, min_processed_fraction)]
    order = np.argsort(np.array([e.start.mjd for e in done], dtype=float), kind="stable") if done else []
    done = [done[int(k)] for k in order]
    shutter = np.concatenate([[0.0], np.cumsum([float(e.exposure_s) for e in done])])
    cover = [0.0] + [cadence_coverage(done[:k + 1], footprints, prob, tuple(filters), cadence_s,
                                      min_processed_fraction=min_processed_fraction) for k in range(len(done))]
    return np.column_stack([shutter, np.asarray(cover, dtype=float)])


def subset_curve(executed: Iterable[ExecutedExposure], footprints: Any, prob: np.ndarray,
                 filters: Sequence[str] = ("g", "r"), cadence_s: float = 0.0,
                 min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> np.ndarray:
    """Cumulative open-shutter time and coverage of the executed record's covered fields, best first.

    A tighter stand-in than the time-ordered prefix (:func:`executed_curve`)
    for the plan a budget allows: the fields the record covers by the pair
    rule, taken greedily by probability gained (beyond the fields already
    taken) per open-shutter second, each field costing all its done
    exposures (a third visit included).  Each field keeps its exposures at
    the times they were executed, so a prefix of this order is a sub-schedule
    of what was executed (every pair as far apart as it was); it is not run
    through the executor again.  Fields that are never covered (a visit
    without its pair) are left out: they add time and no coverage.

    Returns
    -------
    numpy.ndarray
        Shape (m + 1, 2), m covered fields: row k is (open-shutter seconds of
        the first k fields' done exposures, their coverage); row 0 is (0, 0).
        Ties in gain keep the lower field ID first.
    """
    from ..scheduler_core.sequences import covered_fields

    done = [e for e in executed if is_done(e, min_processed_fraction)]
    fields = sorted(covered_fields(done, tuple(filters), min_processed_fraction, cadence_s))
    cost = {f: sum(float(e.exposure_s) for e in done if int(e.field_id) == f) for f in fields}
    pixels = {f: footprints.pixels(f) for f in fields}
    taken = np.zeros(prob.shape, dtype=bool)
    rows, spent, left = [(0.0, 0.0)], 0.0, list(fields)
    while left:
        gains = np.array([prob[pixels[f]][~taken[pixels[f]]].sum() / cost[f] for f in left])
        f = left.pop(int(np.argmax(gains)))
        taken[pixels[f]] = True
        spent += cost[f]
        rows.append((spent, float(prob[taken].sum())))
    return np.asarray(rows, dtype=float)


def coverage_at(curve: np.ndarray | Sequence[Sequence[float]], budget_s: float,
                tolerance_s: float = TOLERANCE_S) -> float:
    """Coverage of the longest prefix whose open-shutter time is within ``budget_s`` (s).

    Parameters
    ----------
    curve : array-like
        :func:`executed_curve`'s (n + 1, 2) rows, open-shutter seconds non-decreasing.
    budget_s : float
        The open-shutter time allowed (s), >= 0.
    tolerance_s : float
        A prefix may exceed the budget by this much (s).

    Returns
    -------
    float
        The coverage; 0 when not even the first exposure fits (or the curve is empty).
    """
    c = np.asarray(curve, dtype=float).reshape(-1, 2)
    if not np.isfinite(budget_s) or budget_s < 0:
        raise ValueError(f"budget_s must be a finite number >= 0, got {budget_s}")
    fits = np.flatnonzero(c[:, 0] <= budget_s + tolerance_s)
    return float(c[fits[-1], 1]) if fits.size else 0.0


def plan_curve(plan: Any, footprints: Any, prob: np.ndarray, filters: Sequence[str] = ("g", "r"),
               cadence_s: float = 1800.0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`executed_curve` and :func:`subset_curve` of a plan's queue set executed on time, as the
    ``coverage_executed`` column runs it.

    The plan's own filters and cadence when it names them (its ``config``),
    else ``filters`` and ``cadence_s`` (a baseline's plan, judged under the
    row's configuration).  A plan without observations: the one row (0, 0) each.
    """
    from ..scheduler_core.plan.exports import timed_queue_set
    from ..scheduler_core.schedulers.as_executed import execute_plan_queues

    if not plan.observations:
        return np.zeros((1, 2)), np.zeros((1, 2))
    if not plan.config:  # as the bench runs a baseline's plan (scoring._under_config)
        plan = plan.with_(config={"filters": list(filters), "cadence_s": float(cadence_s)})
    seq = tuple(plan.config.get("filters", ("g", "r")))[:2]
    cadence = float(plan.config.get("cadence_s", 1800.0))
    queues, _ = timed_queue_set(plan)
    executed = execute_plan_queues(plan, queues, 0.0)
    return (executed_curve(executed, footprints, prob, seq, cadence),
            subset_curve(executed, footprints, prob, seq, cadence))
