"""Planned coverage counted by the pair rule, the same for every row: what a plan would cover if ZTF took it as written.

A plan's ``coverage`` (the checker's) counts every field it names; a
baseline's schedule may name fields observed in one filter only, or outside
their windows.  :func:`planned_pair_coverage` counts a field only when the
plan has exposures of the sequence's first two filters (F1) at least the
cadence apart (E3, :func:`~mushrooms.scheduler_core.executed.done_pairs`),
each wholly inside its field's window (the checker's own Sun, airmass,
hour-angle and mount, Moon rules:
:func:`~mushrooms.scheduler_core.plan.checker.exposures_in_windows`) -
the rule the executed coverage applies to the telescope's records
(:func:`~mushrooms.scheduler_core.schedulers.as_executed.cadence_coverage`), with
every planned exposure taken as done.  Slews and overlaps are the
checker's verdict and the executed coverage's business, not this count's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from astropy.time import TimeDelta

from ..scheduler_core.executed import ExecutedExposure
from ..scheduler_core.plan.checker import exposures_in_windows
from ..scheduler_core.schedulers.as_executed import cadence_coverage

__all__ = ["planned_pair_coverage", "planned_records", "open_shutter_s"]


def planned_records(plan: Any, config: Any) -> list[ExecutedExposure]:
    """The plan's exposures inside their windows, on known fields, as done records (processed, fraction 1)."""
    obs = plan.observations
    if not obs:
        return []
    inside = exposures_in_windows(plan, config)
    return [ExecutedExposure(int(o.field_id), o.filter, plan.start + TimeDelta(float(o.start), format="sec"),
                             float(o.exposure_s), 1.0, "processed")
            for o, ok in zip(obs, inside) if ok and o.exposure_s > 0]


def planned_pair_coverage(plan: Any, footprints: Any, prob: np.ndarray, config: Any) -> float:
    """Probability inside the fields the plan pairs (module notes) under ``config``'s filters and cadence.

    Parameters
    ----------
    plan : Plan
        Any row's plan (times in s since its start).
    footprints : Footprints
        Field footprints at the map's resolution; fields outside them (not
        in ZTF's grid) never count.
    prob : numpy.ndarray
        The map's probability per pixel (NESTED, ``footprints.nside``).
    config : PlanningConfig
        Filter sequence (its first two pair a field), cadence (s) and the
        window rules.

    Returns
    -------
    float
        Coverage in [0, 1]; 0 for a plan without exposures.
    """
    known = {int(f) for f in np.asarray(footprints.field_ids)}
    records = [r for r in planned_records(plan, config) if r.field_id in known]
    if not records:
        return 0.0
    return float(cadence_coverage(records, footprints, prob, tuple(config.filters), float(config.cadence_s)))


def open_shutter_s(plan: Any) -> float:
    """Telescope time with the shutter open (s): the sum of the plan's exposure times."""
    return float(sum(float(o.exposure_s) for o in plan.observations))
