"""Which telescope a plan document is for, and where it stands: what a summary says of its site.

A plan records its telescope in ``config.telescopes`` (absent: ZTF alone, as
every ZTF plan); the site's name, time zone and position come from that
telescope's description (``[site] name``, ``timezone``; issue 53).  Only
shipped descriptions are read: a document naming a file gets no local
clock (UTC only) and no site name, never a file read on its say-so.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Mapping

__all__ = ["PlanSite", "plan_site", "local_time", "at_site", "site_words"]


@dataclass(frozen=True)
class PlanSite:
    """A plan's telescope and site as summaries name them.

    Attributes
    ----------
    telescope : str
        The document's ``telescope`` (``ZTF``, ``LS4``).
    entry : str
        The ``telescopes`` entry (``ztf``, ``ls4``; a path for a description file).
    name : str
        The site's name (``Palomar``; empty: unknown).
    timezone : str
        IANA zone (empty: local mean time from ``longitude_deg``, or none).
    longitude_deg : float or None
        East positive (deg); None when the site is unknown.
    """

    telescope: str
    entry: str
    name: str
    timezone: str
    longitude_deg: float | None

    @property
    def known(self) -> bool:
        """The entry is a shipped description (its site and grid can be used)."""
        return self.longitude_deg is not None


@lru_cache(maxsize=16)
def _shipped(entry: str) -> tuple[str, str, float] | None:
    from ..scheduler_core.instruments import load_description
    from ..scheduler_core.instruments.names import shipped_telescopes

    if entry not in shipped_telescopes():
        return None
    site = load_description(entry).site
    return site.name, site.timezone, float(site.longitude_deg)


def plan_site(doc: Mapping[str, Any]) -> PlanSite:
    """The telescope and site of a plan (or not_observable) document."""
    from ..handlers.text import storable as shown  # facts.shown itself, without the facts <-> site cycle

    listed = (doc.get("config") or {}).get("telescopes") if isinstance(doc.get("config"), Mapping) else None
    entry = str(listed[0]) if isinstance(listed, (list, tuple)) and listed else "ztf"
    telescope = shown(doc.get("telescope") or entry.upper(), 40)
    try:
        found = _shipped(entry)
    except Exception:  # a damaged install: no site words, never a failed summary
        found = None
    if found is None:
        return PlanSite(telescope, shown(entry, 200), "", "", None)
    return PlanSite(telescope, entry, found[0], found[1], found[2])


def site_words(telescope: str) -> str:
    """`` at La Silla`` for a shipped telescope's name (its description's ``[site] name``); empty otherwise."""
    try:
        found = _shipped(str(telescope))
    except Exception:  # a damaged install: no site words, never a failed message
        return ""
    return f" at {found[0]}" if found and found[0] else ""


def local_time(t: dt.datetime, site: PlanSite) -> str | None:
    """The site's clock time with its zone (``20:57 PDT``; ``01:13 LMT`` without a zone); None when unknown."""
    if site.timezone:
        try:
            from zoneinfo import ZoneInfo

            return t.astimezone(ZoneInfo(site.timezone)).strftime("%H:%M %Z")
        except Exception:  # no time-zone database: the local mean time below
            pass
    if site.longitude_deg is None:
        return None
    return (t + dt.timedelta(hours=site.longitude_deg / 15.0)).strftime("%H:%M") + " LMT"


def at_site(t: dt.datetime, site: PlanSite, named: bool = True) -> str:
    """`` (20:57 PDT at Palomar)`` after a UTC time: the site's clock and name; empty when unknown."""
    clock = local_time(t, site)
    if clock is None:
        return ""
    return f" ({clock} at {site.name})" if named and site.name else f" ({clock})"
