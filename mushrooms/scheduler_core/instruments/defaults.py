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

__all__ = ["planning_defaults", "planning_filters", "telescope_entry"]

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


def planning_defaults(telescope: TelescopeDescription) -> dict[str, Any]:
    """``[scheduler]`` values from ``[limits]``, ``[planning]`` and ``[overheads]`` of a description.

    Examples
    --------
    >>> from mushrooms.scheduler_core.instruments import load_description
    >>> d = planning_defaults(load_description("ls4"))
    >>> d["exposure_s"], d["filters"], d["dec_min_deg"], d["slew"]["readout_s"]
    (45.0, ['i'], -90.0, 10.0)
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
            "filter_change_s": plan.filter_change_s, "slew_estimate_s": plan.slew_estimate_s, "slew": slew}


def telescope_entry(telescope: TelescopeDescription) -> str:
    """How ``[scheduler] telescopes`` (and a plan's recorded configuration) names a description.

    A shipped telescope by its name; any other description by its file's path.
    """
    if telescope.name in shipped_telescopes():
        from .loader import DATA_DIR

        if Path(telescope.path).resolve() == (DATA_DIR / f"{telescope.name}.toml").resolve():
            return telescope.name
    return str(telescope.path)
