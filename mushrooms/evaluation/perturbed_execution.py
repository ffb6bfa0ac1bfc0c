"""The executor's overheads and weather perturbed, in the scoring only.

The planner predicts execution with the nominal telescope model
(:class:`~mushrooms.scheduler_core.telescope.timing.TelescopeTiming`: ztf_sim's
8 s readout, 135 s filter change, the P48's slew axes) and a clear sky.  The
independent scoring replays each plan's queues through the same executor
with a telescope and a sky the planner did not see, one seeded draw per
realisation:

* **overheads**: every slew, settle and readout time scaled by a factor
  uniform in [0.8, 1.2] (:meth:`TelescopeTiming.scaled`), the filter change
  uniform in [90, 135] s (ZTF's measured exchange is faster than ztf_sim's
  135 s bound; both ends are kept);
* **weather** (``weather=True``): the plan's exposures are grouped into
  nights (gaps over 4 h); each night independently is lost whole with
  probability 0.21, partly with probability 0.46 (one closure lasting a
  fraction of the night uniform in [0, 0.6], mean 0.3, at a uniform time),
  or clear.  The three numbers are the Palomar 48-inch's own history as
  ztf_sim replays it (``data/weather_blocks.db``: PTF exposures per 30-min
  block, 2010-2015; a block with 5 or more exposures observable, ztf_sim's
  ``check_historical_observability``): of the dark time (Sun below -12 deg)
  PTF observed 61-65 %, 19-25 % of the nights not at all and 40-57 % in
  part, losing 24-35 % of those (``benchmarks/results/science/scoring/README.md``).
  That history counts every reason PTF was not observing, so it is a
  pessimistic weather model.

The executor then runs unchanged (:func:`~.queue_sim.execute_plan`): a closure
aborts the exposure it cuts and the queues wait for the reopening.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..scheduler_core.executed import ExecutedExposure
from ..scheduler_core.plan.document import Plan
from ..scheduler_core.telescope.timing import TelescopeTiming

__all__ = ["Perturbation", "SLEW_FACTOR_RANGE", "FILTER_CHANGE_RANGE_S", "NIGHT_LOST_P", "NIGHT_PARTIAL_P",
           "PARTIAL_LOSS_MAX", "NIGHT_GAP_S", "plan_nights_s", "draw_perturbation", "perturbed_timing",
           "submitted_queues", "execute_perturbed"]

#: Slew, settle and readout scale factor range.
SLEW_FACTOR_RANGE = (0.8, 1.2)
#: Filter-change time range (s).
FILTER_CHANGE_RANGE_S = (90.0, 135.0)
#: Probability a night is lost whole; that it is lost in part (PTF 2010-2015 as ztf_sim replays it).
NIGHT_LOST_P = 0.21
NIGHT_PARTIAL_P = 0.46
#: Largest fraction of a night one partial closure takes (uniform from 0: mean 0.3).
PARTIAL_LOSS_MAX = 0.6
#: A gap longer than this (s) between two planned exposures starts a new night.
NIGHT_GAP_S = 4 * 3600.0


@dataclass(frozen=True)
class Perturbation:
    """One draw of the telescope and the sky.

    Attributes
    ----------
    slew_factor : float
        Scale of every slew, settle and readout time.
    filter_change_s : float
        Filter exchange (s).
    closures_s : tuple of (float, float)
        Dome closed (s since the plan's start).
    """

    slew_factor: float
    filter_change_s: float
    closures_s: tuple[tuple[float, float], ...] = ()


def plan_nights_s(plan: Plan, gap_s: float = NIGHT_GAP_S) -> list[tuple[float, float]]:
    """The plan's nights: spans (s since its start) of exposures without a gap over ``gap_s``."""
    if not plan.observations:
        return []
    starts = np.array([o.start for o in plan.observations], float)
    ends = starts + np.array([o.exposure_s for o in plan.observations], float)
    order = np.argsort(starts)
    starts, ends = starts[order], ends[order]
    cut = np.flatnonzero(starts[1:] - np.maximum.accumulate(ends)[:-1] > gap_s) + 1
    return [(float(s[0]), float(e.max())) for s, e in zip(np.split(starts, cut), np.split(ends, cut))]


def _closures(nights: list[tuple[float, float]], rng: np.random.Generator) -> tuple[tuple[float, float], ...]:
    """One closure per night lost whole or in part (the model of the module notes)."""
    out = []
    for a, b in nights:
        u, frac, where = rng.random(), rng.uniform(0.0, PARTIAL_LOSS_MAX), rng.random()
        length = b - a
        if u < NIGHT_LOST_P:
            out.append((a - 1.0, b + 1.0))
        elif u < NIGHT_LOST_P + NIGHT_PARTIAL_P and frac * length > 0:
            start = a + where * (1.0 - frac) * length
            out.append((start, start + frac * length))
    return tuple(out)


def draw_perturbation(plan: Plan, seed: int | np.random.Generator, weather: bool = True) -> Perturbation:
    """A seeded perturbation of the telescope (and, with ``weather``, the sky) for one plan."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    factor = float(rng.uniform(*SLEW_FACTOR_RANGE))
    change = float(rng.uniform(*FILTER_CHANGE_RANGE_S))
    closures = _closures(plan_nights_s(plan), rng) if weather else ()
    return Perturbation(slew_factor=factor, filter_change_s=change, closures_s=closures)


def perturbed_timing(p: Perturbation, base: TelescopeTiming = TelescopeTiming()) -> TelescopeTiming:
    """``base`` with its slews, settle and readout scaled and its filter change replaced."""
    return dataclasses.replace(base.scaled(p.slew_factor), filter_change_s=p.filter_change_s)


def submitted_queues(plan: Plan) -> list[dict[str, Any]]:
    """The queue set the service submits for the plan (timed, with the closes that survive a slower telescope).

    It depends on the plan only, not on the perturbation: make it once and
    execute it under every draw (:func:`execute_perturbed`).
    """
    from ..scheduler_core.plan.exports import timed_queue_set

    return list(timed_queue_set(plan, robust=True)[0]) if plan.observations else []


def execute_perturbed(plan: Plan, p: Perturbation | None = None,
                      queues: Sequence[dict[str, Any]] | None = None) -> tuple[ExecutedExposure, ...]:
    """The executed record of the plan's queue set under ``p`` (None: the nominal executor, the planner's).

    ``queues``: the plan's :func:`submitted_queues`, when already made (default: made here).
    """
    from ..scheduler_core.schedulers.as_executed import execute_plan_queues

    if p is None:
        return execute_plan_queues(plan, queues)
    return execute_plan_queues(plan, queues, 0.0, perturbed_timing(p), closures_s=p.closures_s)
