"""Where a plan's exposures are on the sky, for the summaries: the Moon's distance and the area covered.

Both come from the plan document and the scheduler's own models (its
ephemeris, :func:`~mushrooms.scheduler_core.sky.ephemeris.ephemeris`, the
Moon as seen from the plan's site; its field footprints at the plan's HEALPix
resolution), so the summary says what the scheduler saw.  A summary is
never refused for them: what cannot be computed is left out (None).
"""

from __future__ import annotations

import logging
from functools import lru_cache
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


def covered_area_deg2(field_ids: Sequence[int], nside: int, entry: str = "ztf",
                      filters: Sequence[str] = ()) -> float | None:
    """Sky area (deg²) of the union of the fields' footprints on the plan's own telescope; None when the
    fields, the resolution or the telescope are unknown.

    ZTF (``entry`` ``"ztf"``): its 16 CCDs at HEALPix ``nside``, as every ZTF summary has said.  Another
    shipped telescope: its own grid and the detectors behind the covering filters (``filters``, the plan's
    ``config.filters``; its description's when empty; a filter it lacks: no area), at a resolution fine
    enough for its camera (:func:`~..scheduler_core.sky.covered_area.covered_area_deg2`).  A description
    file named by a document is never read: no area.
    """
    if not field_ids or not nside:
        return None
    try:
        import healpy as hp

        from ..scheduler_core.sky.fields import field_footprints, load_ztf_fields

        if entry != "ztf":
            return _own_area_deg2(tuple(sorted({int(f) for f in field_ids})), int(nside), str(entry),
                                  tuple(str(f) for f in filters))
        pixels = field_footprints(load_ztf_fields(), int(nside)).union(sorted({int(f) for f in field_ids}))
        return float(len(pixels)) * float(hp.nside2pixarea(int(nside), degrees=True))
    except Exception as exc:  # an unknown field id, an odd resolution: the fact is left out
        log.warning("event=summary_area_unknown error=%r", str(exc))
        return None


@lru_cache(maxsize=32)
def _own_area_deg2(field_ids: tuple[int, ...], nside: int, entry: str, filters: tuple[str, ...]) -> float | None:
    """The area on a shipped telescope's own grid and covering detectors (None for anything else); kept
    for the revision's other texts (its summary, page, parts' lines and webhook words count it once)."""
    from ..scheduler_core.instruments import load_description
    from ..scheduler_core.instruments.active import covering_polygons
    from ..scheduler_core.instruments.names import shipped_telescopes
    from ..scheduler_core.sky.covered_area import covered_area_deg2 as own_area
    from ..scheduler_core.sky.fields import Camera, telescope_grid

    if entry not in shipped_telescopes():
        return None
    telescope = load_description(entry)
    chosen = filters or tuple(telescope.planning.filters)
    if any(f not in telescope.filters for f in chosen):  # not this telescope's plan: no area said
        return None
    camera = Camera(covering_polygons(telescope, chosen), telescope.footprint.radius_deg)
    return own_area(telescope_grid(telescope), field_ids, camera, nside)


def plan_area_deg2(doc: Any) -> float | None:
    """The area a plan document's fields cover on its own telescope (:func:`covered_area_deg2`), None when
    unknown (not a plan, no fields, a telescope not shipped)."""
    try:
        from .facts import plan_facts

        if not isinstance(doc, dict) or doc.get("type") != "plan":
            return None
        facts = plan_facts(doc)
        if not facts.rows:
            return None
        return covered_area_deg2([r.field_id for r in facts.rows], facts.nside or 0, facts.site.entry,
                                 facts.sequence)
    except Exception as exc:  # a document of another version: the fact is left out
        log.warning("event=summary_area_unknown error=%r", str(exc))
        return None


def part_area_deg2(part: Any) -> float | None:
    """The area a telescope part's plan covers (its folder's ``plan.json``, written by the service), None
    for a part not exported or whose plan cannot be read."""
    import json
    from pathlib import Path

    if not isinstance(part, dict) or part.get("state") != "exported" or not part.get("folder"):
        return None
    try:
        doc = json.loads((Path(str(part["folder"])) / "plan.json").read_text())
    except (OSError, ValueError) as exc:
        log.warning("event=summary_area_unknown error=%r", str(exc))
        return None
    return plan_area_deg2(doc)


def area_words(area: float | None) -> str:
    """`` (fields cover 1,234 deg²)``; empty when unknown."""
    return "" if area is None else f" (fields cover {area:,.0f} deg²)"
