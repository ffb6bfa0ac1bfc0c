"""The nights ahead at a telescope's site: each night's validity window, twilight to twilight (N1).

A night is the dark part of one block from local noon to local noon
(:func:`night_anchor`: :data:`~.visibility.GRID_ANCHOR`, Palomar's local
mean noon, moved by the site's longitude in whole minutes;
:data:`~.visibility.NIGHT_S`): the Sun at
most ``sun_alt_max_deg`` high.  Its window runs from the first to the last
time of a one-minute grid at which the Sun is that low, so it lies inside
the true dark interval (the Sun's altitude is monotonic across a twilight),
by less than a minute at each end.  The Sun's altitude is the ephemeris's
(:mod:`.ephemeris`, E1-E3: astropy every 10 minutes, interpolated), within
1e-3 deg of astropy's at every grid time: where astropy's altitude at a grid
time lies that close to the limit, a twilight may move by one grid step.
The equations are in ``docs/design/replan.md`` (N1-N3).
"""

from __future__ import annotations

import numpy as np
from astropy.time import Time, TimeDelta

from ..config import PlanningConfig
from .ephemeris import ephemeris
from .visibility import GRID_ANCHOR, NIGHT_S, PALOMAR, site

__all__ = ["night_windows", "night_evening", "night_anchor", "NIGHT_GRID_S"]

#: Step (s) of the grid on which twilights are found.
NIGHT_GRID_S = 60.0


def night_anchor(telescope: str = "ztf") -> Time:
    """Local mean noon at the telescope's site on 2000-01-01, in whole minutes from :data:`GRID_ANCHOR` (UTC).

    Nights are split at the site's noon, so a site's night is found whole
    wherever it lies (a site far east of Palomar has its night across
    Palomar's noon).  For ZTF (Palomar) it is :data:`GRID_ANCHOR` itself.

    Parameters
    ----------
    telescope : str
        A ``telescopes`` entry (``"ztf"``, a shipped name or a description path).
    """
    if telescope == "ztf":
        return GRID_ANCHOR
    east_deg = float(site(telescope).lon.deg) - PALOMAR[1]
    east_deg = (east_deg + 180.0) % 360.0 - 180.0
    # 4 minutes of time per degree east, earlier noon; on the minute grid of the twilights
    shift_s = np.round(-east_deg * 240.0 / NIGHT_GRID_S) * NIGHT_GRID_S
    return GRID_ANCHOR + TimeDelta(shift_s, format="sec")


def night_windows(start: Time, config: PlanningConfig, nights: int) -> tuple[tuple[Time, Time], ...]:
    """The validity windows of the next ``nights`` nights from ``start`` (N1).

    Parameters
    ----------
    start : astropy.time.Time
        From when (UTC); a night already under way starts at ``start``
        (rounded up to the grid), one already over is skipped.
    config : PlanningConfig
        ``sun_alt_max_deg``: the Sun's highest altitude at night (deg).
    nights : int
        How many (>= 1).

    Returns
    -------
    tuple of (Time, Time)
        ``(evening twilight, morning twilight)`` per night, in time order.

    Raises
    ------
    ValueError
        ``nights < 1``, or no night in ``nights + 2`` days (a Sun limit the
        Sun never goes below).
    """
    if nights < 1:
        raise ValueError(f"nights must be >= 1, got {nights}")
    start = Time(start, scale="utc")
    anchor = night_anchor(config.telescope)
    t0 = float((start - anchor).to_value("s"))
    block = int(np.floor(t0 / NIGHT_S))
    out: list[tuple[Time, Time]] = []
    for b in range(block, block + nights + 2):
        offsets = np.arange(b * NIGHT_S, (b + 1) * NIGHT_S, NIGHT_GRID_S)
        offsets = offsets[offsets >= t0 - 1e-6]
        if offsets.size == 0:
            continue
        times = anchor + TimeDelta(offsets, format="sec")
        dark = np.flatnonzero(ephemeris(times, site(config.telescope)).sun_alt_deg <= config.sun_alt_max_deg)
        if dark.size == 0:
            continue
        # (N1) the night: first to last grid time with the Sun below the limit, never before the start
        out.append((times[dark[0]], times[dark[-1]]))
        if len(out) == nights:
            return tuple(out)
    raise ValueError(f"only {len(out)} night(s) with the Sun below {config.sun_alt_max_deg:g} deg "
                     f"in the {nights + 2} days from {start.isot[:19]}")


def night_evening(start: Time, config: PlanningConfig) -> Time:
    """(N5) The evening twilight ``s_n`` of the night ``start`` plans: the true one when the night is under way.

    :func:`night_windows` starts a night under way at ``start``; what the
    night already did (N4: the exposures counted as done with ``revisit``)
    began at its real evening twilight, found from the noon that opens the
    block holding ``start``.  In daytime it is the coming night's evening.
    """
    start = Time(start, scale="utc")
    (evening, morning), = night_windows(start, config, 1)
    anchor = night_anchor(config.telescope)
    block = np.floor(float((start - anchor).to_value("s")) / NIGHT_S) * NIGHT_S
    noon = anchor + TimeDelta(block, format="sec")
    if noon < start:
        (real, end), = night_windows(noon, config, 1)
        if abs(float((end - morning).to_value("s"))) < NIGHT_GRID_S:  # the same night
            return real
    return evening
