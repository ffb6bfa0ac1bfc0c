"""The following nights: one plan per night, each on what the nights before achieved (N1-N3).

``[scheduler] nights = N`` (:class:`~.config.PlanningConfig`): night ``n``'s
plan covers that night's validity window (:func:`~.sky.twilight.night_windows`,
N1) and is made by :func:`~.replan.plan_remaining` on what nights ``<= n - 1``
achieved: the executed record where it is known, the earlier nights' plans
(taken as done) otherwise (N2), so a later night's objective is the
probability still uncovered (N3).  The equations are in
``docs/design/replan.md``.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Sequence

from astropy.time import Time

from .config import PlanningConfig
from .executed import MIN_PROCESSED_FRACTION, ExecutedExposure, counted_for_night
from .plan.document import EventInfo, Plan
from .problem import StopCheck
from .sky.fields import FieldGrid
from .sky.skymap import SkyMap

__all__ = ["plan_nights", "as_planned", "counted_for_night"]

log = logging.getLogger(__name__)


def as_planned(plan: Plan) -> tuple[ExecutedExposure, ...]:
    """A plan's exposures as if the telescope had done them all (N2): fully reduced, at their planned times."""
    return tuple(ExecutedExposure(o.field_id, o.filter, plan.absolute_time(o.start), o.exposure_s, 1.0, "processed")
                 for o in plan.observations)


def plan_nights(skymap: SkyMap, config: PlanningConfig, start: Time | None = None,
                executed: Sequence[ExecutedExposure] = (), *, event: EventInfo | None = None,
                min_processed_fraction: float = MIN_PROCESSED_FRACTION, solver: str | None = None,
                should_stop: StopCheck | None = None, grid: FieldGrid | None = None) -> tuple[Plan, ...]:
    """Plan ``config.nights`` nights from ``start``, one checked plan per night.

    Parameters
    ----------
    skymap : SkyMap
        Sky map at ``config.nside``.
    config : PlanningConfig
        Planning parameters; ``nights`` of them (``horizon_h`` is not used:
        each plan covers its night).
    start : astropy.time.Time, optional
        From when (default the merger time); a night under way is planned
        from ``start``.
    executed : sequence of ExecutedExposure
        What the telescope did already (counts for every night).
    event : EventInfo, optional
        The alert answered.
    min_processed_fraction : float
        Done rule of the executed record (E1).
    solver : str, optional
        Scheduler name (default ``config.solver``).
    should_stop : callable, optional
        Polled by every night's scheduler.
    grid : FieldGrid, optional
        The field grid.

    Returns
    -------
    tuple of Plan
        In night order; plan ``n`` starts and ends at night ``n``'s
        twilights (N1), its ``config.horizon_h`` that night's length.

    Raises
    ------
    InputError
        No start time (and no merger time in the map).
    """
    from .clock import on_merger_clock
    from .errors import InputError
    from .replan import plan_remaining
    from .sky.twilight import night_evening, night_windows

    skymap, event = on_merger_clock(skymap, event)
    if start is None:
        if skymap.event_time is None:
            raise InputError("the sky map has no event time (DATE-OBS); give a start time")
        start = skymap.event_time
    start = Time(start, scale="utc")
    windows = night_windows(start, config, config.nights)
    done: list[ExecutedExposure] = list(executed)
    plans: list[Plan] = []
    for n, (evening, morning) in enumerate(windows, 1):
        night = dataclasses.replace(config, horizon_h=float((morning - evening).to_value("h")))
        # (N2) night n on what nights < n achieved: the executed record, the earlier plans as done
        # (N4) revisit: this night's own only, (N5) from its real evening when the start is mid-night
        counted = counted_for_night(done, night_evening(evening, config) if n == 1 else evening, config.revisit)
        plan = plan_remaining(skymap, night, evening, counted, event=event, solver=solver, should_stop=should_stop,
                              grid=grid, min_processed_fraction=min_processed_fraction)
        log.info("night %d of %d, %s to %s: %d fields, %d exposures, adds %.4f to %.4f",
                 n, len(windows), evening.isot[:16], morning.isot[:16], plan.metrics.n_fields,
                 plan.metrics.n_exposures, plan.metrics.coverage, plan.metrics.coverage_executed)
        plans.append(plan)
        done.extend(as_planned(plan))
    return tuple(plans)
