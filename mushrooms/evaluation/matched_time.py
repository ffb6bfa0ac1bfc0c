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
:func:`coverage_at` reads it at a budget.  Pure functions, no I/O.
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

import numpy as np

from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, ExecutedExposure, is_done
from ..scheduler_core.schedulers.as_executed import cadence_coverage

__all__ = ["executed_curve", "coverage_at", "plan_curve", "TOLERANCE_S"]

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
               cadence_s: float = 1800.0) -> np.ndarray:
    """:func:`executed_curve` of a plan's queue set executed on time, as the ``coverage_executed`` column runs it.

    The plan's own filters and cadence when it names them (its ``config``),
    else ``filters`` and ``cadence_s`` (a baseline's plan, judged under the
    row's configuration).  A plan without observations: the one row (0, 0).
    """
    from ..scheduler_core.plan.exports import timed_queue_set
    from ..scheduler_core.schedulers.as_executed import execute_plan_queues

    if not plan.observations:
        return np.zeros((1, 2))
    if not plan.config:  # as the bench runs a baseline's plan (scoring._under_config)
        plan = plan.with_(config={"filters": list(filters), "cadence_s": float(cadence_s)})
    seq = tuple(plan.config.get("filters", ("g", "r")))[:2]
    cadence = float(plan.config.get("cadence_s", 1800.0))
    queues, _ = timed_queue_set(plan)
    return executed_curve(execute_plan_queues(plan, queues, 0.0), footprints, prob, seq, cadence)
