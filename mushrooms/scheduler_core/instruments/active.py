"""The planner's view of the telescope a configuration plans (phase 2, ``docs/design/telescopes.md`` section 4).

``config.telescope`` (the first of ``[scheduler] telescopes``) names a
shipped description or a description file; these functions give the planner
what it reads from it: the field grid, the detectors of the covering
filters and the site (the depth model: :func:`~..source.depth.depth_model`).  ZTF's
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

__all__ = ["telescope_name", "description_of", "covering_polygons", "site_tuple"]


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
