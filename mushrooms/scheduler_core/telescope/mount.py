"""(M1) The mount a configuration plans with: equatorial (ZTF's, timed by RA and Dec) or alt-azimuth.

A description whose ``[[overheads.axes]]`` move in ``azimuth`` and
``altitude`` (and not in ``ha``, ``dec``) is an alt-azimuth mount (WINTER):
its slews are timed on those axes at the slew's time
(:class:`~.slew.AltAzMount`, ``docs/design/telescopes.md`` M1).  ZTF never
reads a description here: its slews are timed as always.
"""

from __future__ import annotations

from typing import Any

import erfa
from astropy import units as u
from astropy.time import Time

from .slew import AltAzMount

__all__ = ["is_altaz", "altaz_mount"]


def is_altaz(coordinates: set[str]) -> bool:
    """(M1) Axes moving in azimuth or altitude and in neither hour angle nor declination."""
    return bool(coordinates & {"azimuth", "altitude"}) and not coordinates & {"ha", "dec"}


def altaz_mount(config: Any, start: Time) -> AltAzMount | None:
    """The alt-azimuth mount of ``config.telescope`` for a horizon starting at ``start``; None: equatorial.

    Parameters
    ----------
    config : PlanningConfig
        Its ``telescope`` names the description (``ztf``: None without reading one).
    start : astropy.time.Time
        The horizon's start (``t = 0`` of the schedulers' times).
    """
    if config.telescope == "ztf":
        return None
    from ..instruments.active import description_of

    telescope = description_of(config)
    if not is_altaz({a.coordinate for a in telescope.overheads.axes}):
        return None
    site, start = telescope.site, Time(start)
    lst0 = start.sidereal_time("apparent", longitude=float(site.longitude_deg) * u.deg).deg
    to_date = erfa.pnm06a(start.tt.jd1, start.tt.jd2)  # ICRS (GCRS axes) -> true equator and equinox of date
    return AltAzMount(float(site.latitude_deg), float(lst0), tuple(tuple(float(x) for x in row) for row in to_date))
