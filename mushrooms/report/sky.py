"""Where a plan's exposures are on the sky, for the summaries: the Moon's distance and the area covered.

Both come from the plan document and the scheduler's own models (its
ephemeris, :func:`~mushrooms.scheduler_core.sky.ephemeris.ephemeris`, the
Moon as seen from the plan's site; its field footprints at the plan's HEALPix
resolution), so the summary says what the scheduler saw.  A summary is
never refused for them: what cannot be computed is left out (None).
"""

from __future__ import annotations

import logging
from typing import Any, Sequence

import numpy as np

from .facts import ExposureRow

__all__ = ["moon_distances", "covered_area_deg2"]

log = logging.getLogger("mushrooms.report")


def moon_distances(rows: Sequence[ExposureRow], where: Any = None) -> list[float | None]:
    """Each exposure's distance from the Moon at its start (deg), None when unknown.

    Topocentric from the plan's site (``where``: a :class:`~.site.PlanSite`; default and for
    ZTF Palomar); None for a telescope whose site is not known (a description file).
    """
    known = [i for i, r in enumerate(rows) if r.ra is not None and r.dec is not None]
    out: list[float | None] = [None] * len(rows)
    if not known or (where is not None and not where.known):
        return out
    try:
        from astropy.time import Time

        from ..scheduler_core.sky.ephemeris import ephemeris
        from ..scheduler_core.sky.visibility import site

        location = site("ztf" if where is None else where.entry)
        sky = ephemeris(Time([rows[i].start.replace(tzinfo=None) for i in known], scale="utc"), location)
        moon_ra, moon_dec = np.radians(sky.moon_ra_deg), np.radians(sky.moon_dec_deg)
        ra = np.radians([float(rows[i].ra) for i in known])
        dec = np.radians([float(rows[i].dec) for i in known])
        cos_sep = np.sin(dec) * np.sin(moon_dec) + np.cos(dec) * np.cos(moon_dec) * np.cos(ra - moon_ra)
        for i, sep in zip(known, np.degrees(np.arccos(np.clip(cos_sep, -1.0, 1.0)))):
            out[i] = float(sep)
    except Exception as exc:  # no ephemeris (a time out of range, a damaged install): the column stays empty
        log.warning("event=summary_moon_unknown error=%r", str(exc))
    return out


def covered_area_deg2(field_ids: Sequence[int], nside: int) -> float | None:
    """Sky area (deg²) of the union of the fields' footprints (their CCDs) at HEALPix ``nside``; None when
    the fields or the resolution are unknown."""
    if not field_ids or not nside:
        return None
    try:
        import healpy as hp

        from ..scheduler_core.sky.fields import field_footprints, load_ztf_fields

        pixels = field_footprints(load_ztf_fields(), int(nside)).union(sorted({int(f) for f in field_ids}))
        return float(len(pixels)) * float(hp.nside2pixarea(int(nside), degrees=True))
    except Exception as exc:  # an unknown field id, an odd resolution: the fact is left out
        log.warning("event=summary_area_unknown error=%r", str(exc))
        return None
