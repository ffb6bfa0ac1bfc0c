"""A plan's defaults from a telescope's description: the ``[scheduler]`` keys it sets (phase 2).

``PlanningConfig.for_telescope`` starts from these and lets every key the
``[scheduler]`` table sets win (``docs/design/telescopes.md``, section 4).
For ZTF they equal :class:`~..config.PlanningConfig`'s defaults
(``tests/scheduler/test_ztf_description.py``), so a ZTF plan is today's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .description import TelescopeDescription
from .names import shipped_telescopes
from .reference import ZTF_THRESHOLDS

__all__ = ["planning_defaults", "planning_filters", "telescope_entry", "covering_area_deg2", "threshold_scale",
           "scaled_thresholds"]

#: Slew-model keys by the axis that drives them: an alt-azimuth mount's axes stand in for the equatorial
#: ones (phase 2 times every slew by its equatorial travel; ``docs/design/telescopes.md``, section 4).
_AXES = (("ha", ("ha", "azimuth")), ("dec", ("dec", "altitude")))


def planning_filters(telescope: TelescopeDescription) -> tuple[str, ...]:
    """The description's filter sequence with a repeated visit dropped (``i, i`` -> ``i``).

    Phase 2 plans a sequence that changes filter at every visit (F0); a
    sequence repeating one filter (LS4's ``i, i``, WINTER's ``J, J``) is
    planned as its visits in distinct filters: one visit of a field covers it
    (F1 with k = 1).  Its repeat is the per-telescope cadence rule of phase 3 (J3).
    """
    seq: list[str] = []
    for name in telescope.planning.filters:
        if not seq or seq[-1] != name:
            seq.append(name)
    return tuple(seq)


def covering_area_deg2(telescope: TelescopeDescription) -> float:
    """Area (deg², in the plane of I3) of the detectors a visit in the planning filters covers.

    The detectors behind the covering filters (:func:`~.active.covering_polygons`:
    LS4's ``i`` lies on two of its four quadrants, 10.4 of its 20.7 deg²);
    the whole footprint when no detector lies behind them all (the
    configuration's own check refuses such filters in one line).
    """
    import numpy as np

    from .active import covering_polygons

    try:
        polygons = covering_polygons(telescope, planning_filters(telescope))
    except ValueError:
        polygons = telescope.footprint.polygons
    area = 0.0
    for p in polygons:  # shoelace
        x, y = p[:, 0], p[:, 1]
        area += 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    return area


def threshold_scale(telescope: TelescopeDescription) -> float:
    """(I5) The telescope's covering area over ZTF's (47.7 deg²), at most 1: 1.0 exactly for ZTF.

    At most 1: a camera larger than ZTF's keeps ZTF's thresholds (a huge or
    hostile footprint would otherwise push ``min_coverage`` to 1 or more).
    """
    from .loader import load_description

    own, ztf = covering_area_deg2(telescope), covering_area_deg2(load_description("ztf"))
    return min(own / ztf, 1.0) if own > 0 else 1.0


def scaled_thresholds(telescope: TelescopeDescription) -> dict[str, float]:
    """(I5) ``min_gain`` and ``min_coverage``: ZTF's defaults times :func:`threshold_scale`, to 3 significant digits.

    ZTF's 0.001 and 0.01 (the probability a field must add, and a plan must
    cover) are for a 47.7 deg² field; a field of area ``A`` holds about
    ``A / 47.7`` of what a ZTF field holds of the same sky, so the same rule
    for it is ZTF's thresholds times that ratio (WINTER, 1 deg²:
    2.1e-05 and 0.00021).  For ZTF the ratio is 1.0 and the values are
    ``PlanningConfig``'s defaults exactly.
    """
    scale = threshold_scale(telescope)
    return {key: float(f"{value * scale:.3g}") for key, value in ZTF_THRESHOLDS.items()}


def planning_defaults(telescope: TelescopeDescription) -> dict[str, Any]:
    """``[scheduler]`` values from ``[limits]``, ``[planning]`` and ``[overheads]`` of a description.

    And (I5) ``min_gain``, ``min_coverage`` scaled by the covering area (:func:`scaled_thresholds`).

    Examples
    --------
    >>> from mushrooms.scheduler_core.instruments import load_description
    >>> d = planning_defaults(load_description("ls4"))
    >>> d["exposure_s"], d["filters"], d["dec_min_deg"], d["slew"]["readout_s"]
    (45.0, ['i'], -90.0, 10.0)
    >>> d["min_gain"], d["min_coverage"]  # (I5) ZTF's, times 10.4 / 47.7 deg2
    (0.000217, 0.00217)
    """
    lim, plan, over = telescope.limits, telescope.planning, telescope.overheads
    slew: dict[str, Any] = {"settle_s": over.settle_s, "readout_s": over.readout_s}
    for key, coordinates in _AXES:
        axis = next((a for a in (over.axis(c) for c in coordinates) if a is not None), None)
        if axis is not None:
            slew[f"{key}_accel_deg_s2"] = axis.accel_deg_s2
            slew[f"{key}_vmax_deg_s"] = axis.vmax_deg_s
    return {"airmass_max": lim.airmass_max, "ha_max_h": lim.ha_max_h, "dec_min_deg": lim.dec_min_deg,
            "dec_max_deg": lim.dec_max_deg, "sun_alt_max_deg": lim.sun_alt_max_deg,
            "moon_sep_min_deg": lim.moon_sep_min_deg, "exposure_s": plan.exposure_s,
            "filters": list(planning_filters(telescope)), "cadence_s": plan.cadence_s,
            "filter_change_s": plan.filter_change_s, "slew_estimate_s": plan.slew_estimate_s, "slew": slew,
            **scaled_thresholds(telescope)}


def telescope_entry(telescope: TelescopeDescription) -> str:
    """How ``[scheduler] telescopes`` (and a plan's recorded configuration) names a description.

    A shipped telescope by its name; any other description by its file's path.
    """
    if telescope.name in shipped_telescopes():
        from .loader import DATA_DIR

        if Path(telescope.path).resolve() == (DATA_DIR / f"{telescope.name}.toml").resolve():
            return telescope.name
    return str(telescope.path)
