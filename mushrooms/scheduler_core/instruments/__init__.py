"""Telescopes as descriptions, not code: site, field grid, footprint, filters, overheads, limits, queue.

A description is a TOML file (``scheduler_core/data/telescopes/`` ships
ZTF, LS4, WINTER and DECam, each number's source in ``SOURCES.md`` beside
them); :func:`load_description` reads and checks one into a frozen
:class:`TelescopeDescription`.  The format, how ZTF maps onto it, and the
plan for the planner to read descriptions: ``docs/design/telescopes.md``.

Modules: :mod:`.description` (the dataclasses), :mod:`.schema` (every key's
type, unit and range), :mod:`.validate` (one line per problem),
:mod:`.loader` (files to dataclasses), :mod:`.tessellation` (field grids,
I1-I2), :mod:`.footprint` (detector polygons, I3), :mod:`.limits` (mount
limits, I4); phase 2, the planner reading them: :mod:`.names` (a
``telescopes`` entry, no numpy), :mod:`.defaults` (a plan's defaults),
:mod:`.active` (the description a configuration plans, its covering
detectors and site).  Pure functions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..lazy import lazy_exports

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from .description import (QUEUE_KINDS, DepthTerms, Execution, FieldCentres, FilterTerms, Footprint, KeepOut,
                              Overheads, PlanningDefaults, PointingLimits, SlewAxis, Site, TelescopeDescription)
    from .limits import pointing_allowed
    from .loader import DATA_DIR, description_path, known_telescopes, load_description, parse_description
    from .tessellation import declination_band_grid, points_seen, read_field_list
    from .validate import DescriptionError

#: public name -> the submodule defining it (imported on first use: the schema alone loads no numpy)
_EXPORTS = {
    **{name: ".description" for name in ("QUEUE_KINDS", "DepthTerms", "Execution", "FieldCentres", "FilterTerms",
                                         "Footprint", "KeepOut", "Overheads", "PlanningDefaults", "PointingLimits",
                                         "SlewAxis", "Site", "TelescopeDescription")},
    "pointing_allowed": ".limits",
    **{name: ".loader" for name in ("DATA_DIR", "description_path", "known_telescopes", "load_description",
                                    "parse_description")},
    **{name: ".tessellation" for name in ("declination_band_grid", "points_seen", "read_field_list")},
    "DescriptionError": ".validate",
}

__all__ = list(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
