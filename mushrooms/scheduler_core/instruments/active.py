"""The planner's view of the telescope a configuration plans (phase 2, ``docs/design/telescopes.md`` section 4).

``config.telescope`` (the first of ``[scheduler] telescopes``) names a
shipped description or a description file; these functions give the planner
what it reads from it: the field grid, the detectors of the covering
filters, the site, the mount's keep-out boxes and the depth model.  ZTF's
description holds the values of the planner's constants
(``tests/scheduler/test_ztf_description.py``); a ZTF plan keeps the code
paths it always had (its footprint test, :func:`~..sky.constraints.mount_limits_ok`),
so its plan id and document are today's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .description import TelescopeDescription
from .loader import load_description
from .names import is_path

__all__ = ["telescope_name", "description_of", "covering_polygons", "site_tuple", "depth_model"]


def telescope_name(entry: str) -> str:
    """The telescope's name from a ``telescopes`` entry (a description file's stem is its name)."""
    return Path(entry).stem if is_path(entry) else entry


def description_of(config: Any) -> TelescopeDescription:
    """The description of the telescope ``config`` plans (read once per file version)."""
    return load_description(config.telescope)


def covering_polygons(telescope: TelescopeDescription, filters: tuple[str, ...]) -> tuple[np.ndarray, ...]:
    """The detectors that make a field covered: those behind every filter of the covering visits (F1).

    The covering visits are the sequence's first two (its only one when
    ``k = 1``); a filter without ``detectors`` is behind all of them (LS4's
    ``i`` lies on two quadrants: an ``i`` visit covers the sky under them).

    Raises
    ------
    ValueError
        When no detector lies behind every covering filter (LS4's ``g, i``).
    """
    n = len(telescope.footprint.polygons)
    common = set(range(n))
    for name in filters[:2]:
        behind = telescope.filters[name].detectors
        common &= set(behind) if behind else set(range(n))
    if not common:
        raise ValueError(f"[scheduler] filters {list(filters)!r}: no {telescope.name} detector lies behind "
                         f"{' and '.join(filters[:2])} (filters fixed on the detectors): plan one of them")
    return tuple(telescope.footprint.polygons[i] for i in sorted(common))


def site_tuple(telescope: TelescopeDescription) -> tuple[float, float, float]:
    """(latitude, longitude, height) of the site (deg, deg, m)."""
    s = telescope.site
    return (float(s.latitude_deg), float(s.longitude_deg), float(s.height_m))


def depth_model(config: Any) -> Any:
    """(D1)-(D2) for a telescope: ``C_b = zenith_depth - 1.25 log10(reference_exposure_s / 30 s)`` (section 1).

    A filter without ``reference_depth`` gets a reference far deeper than any
    exposure (99 mag at its zenith seeing): D2 then adds nothing.
    """
    from ..source.depth import ZTF_DEPTH, DepthModel

    if config.telescope == "ztf":  # the calibrated model; ztf.toml's terms equal it (tested)
        return ZTF_DEPTH
    telescope = description_of(config)
    shift = 1.25 * float(np.log10(telescope.depth.reference_exposure_s / 30.0))
    f = telescope.filters
    return DepthModel(
        dark_zenith_depth_30s={b: t.zenith_depth - shift for b, t in f.items()},
        dark_sky_zenith={b: t.sky_zenith for b, t in f.items()},
        extinction={b: t.extinction for b, t in f.items()},
        seeing_airmass_exponent=telescope.depth.seeing_airmass_exponent,
        twilight_slope_mag_per_deg=telescope.depth.twilight_slope_mag_per_deg,
        zenith_fwhm_arcsec={b: t.zenith_fwhm_arcsec for b, t in f.items()},
        reference_depth={b: 99.0 if t.reference_depth is None else t.reference_depth for b, t in f.items()},
        reference_fwhm_arcsec={b: t.zenith_fwhm_arcsec if t.reference_fwhm_arcsec is None
                               else t.reference_fwhm_arcsec for b, t in f.items()},
        sun_minus_v={b: t.sun_minus_v for b, t in f.items()},
        location=site_tuple(telescope))
