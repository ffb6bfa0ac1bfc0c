"""The airmass panel of a plan's picture: each planned field's airmass over the night, the Moon's, and when
each exposure is taken.

Night (Sun below the plan's ``sun_alt_max_deg``) and twilight (Sun below the
horizon) are shaded; a field's curve is thin and grey, its exposures are
drawn on it in their filter's colour, and its id is written at its first
exposure.  Exposures already executed inside the plan's horizon are drawn
as hollow markers (a re-plan's earlier ones are on the sky panels only).
The Moon's altitude is given as an airmass curve while it is up.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

__all__ = ["night_grid", "draw_airmass", "place_field_labels", "shade_night", "AIRMASS_TOP", "SKY_SHADES",
           "FILTER_COLOURS"]

#: Airmass at the top of the panel (the panel's y axis is inverted: 1 at the bottom ... this at the top).
AIRMASS_TOP = 2.6

#: Colours of ZTF's filters (exposures here, the path and the timeline of :mod:`.plotting`).
FILTER_COLOURS = {"g": "#1a9e2f", "r": "#d62728", "i": "#8c564b"}

#: The shades of the sky, one colour each in every panel of the picture (this one and the timeline below it,
#: whose legend names them): twilight (Sun below the horizon) and night (Sun below ``sun_alt_max_deg``).
#: Light enough for the fields' grey airmass curves to show through.
SKY_SHADES = {"twilight": "#d5dcea", "night": "#aab6cc"}


def night_grid(plan: Any, step_s: float = 300.0) -> dict[str, Any]:
    """Hours since the plan start, and the Sun's and Moon's altitude (deg) at Palomar on that grid.

    Returns
    -------
    dict
        ``hours`` (n,), ``sun_alt`` (n,), ``moon_alt`` (n,) in degrees,
        ``times`` (astropy Time, n), ``sun0`` and ``moon0`` (the bodies at
        the start, ICRS) and ``moon_illumination`` (0-1 at the start).
    """
    from astropy.coordinates import AltAz, get_body
    from astropy.time import TimeDelta

    from .scheduler_core.sky.visibility import site

    span = float((plan.end - plan.start).to_value("s"))
    offsets = np.arange(0.0, span + step_s, step_s)
    times = plan.start + TimeDelta(offsets, format="sec")
    frame = AltAz(obstime=times, location=site())
    sun = get_body("sun", times, site())
    moon = get_body("moon", times, site())
    elongation = float(sun[0].separation(moon[0]).rad)
    return {"hours": offsets / 3600.0, "times": times, "sun_alt": sun.transform_to(frame).alt.deg,
            "moon_alt": moon.transform_to(frame).alt.deg, "sun0": sun[0], "moon0": moon[0],
            "moon_illumination": float((1.0 - np.cos(elongation)) / 2.0)}


def _airmass(alt_deg: np.ndarray) -> np.ndarray:
    """sec z, NaN below 5 deg altitude (off the panel)."""
    alt = np.asarray(alt_deg, float)
    return np.where(alt > 5.0, 1.0 / np.sin(np.radians(np.maximum(alt, 5.0))), np.nan)


def shade_night(ax: Any, hours: np.ndarray, sun_alt: np.ndarray, sun_limit: float) -> None:
    """Twilight (Sun below 0 deg) light, night (below ``sun_limit``) darker, as vertical spans."""
    dt = float(hours[1] - hours[0]) if hours.size > 1 else 1.0
    for mask, colour in (((sun_alt < 0) & (sun_alt > sun_limit), SKY_SHADES["twilight"]),
                         (sun_alt <= sun_limit, SKY_SHADES["night"])):
        for h in hours[mask]:
            ax.axvspan(h - dt / 2, h + dt / 2, color=colour, lw=0, zorder=0)


def draw_airmass(ax: Any, plan: Any, grid: dict[str, Any], executed: Sequence[Any] = ()) -> None:
    """The airmass of every planned field over the horizon, its exposures, the Moon; night shaded.

    Parameters
    ----------
    ax : matplotlib Axes
    plan : Plan
    grid : dict
        :func:`night_grid` of the plan.
    executed : sequence of ExecutedExposure
        Exposures done before the plan (drawn hollow at their time, when inside the horizon).
    """
    from astropy import units as u
    from astropy.coordinates import AltAz, SkyCoord
    from matplotlib.lines import Line2D

    from .scheduler_core.sky.visibility import site

    hours, times = grid["hours"], grid["times"]
    sun_limit = float((plan.config or {}).get("sun_alt_max_deg", -12.0))
    shade_night(ax, hours, grid["sun_alt"], sun_limit)
    obs = plan.observations
    fields = list(dict.fromkeys(o.field_id for o in obs))
    if fields:
        first = {o.field_id: o for o in reversed(obs)}
        coords = SkyCoord([first[f].ra for f in fields] * u.deg, [first[f].dec for f in fields] * u.deg)
        frame = AltAz(obstime=times[:, None], location=site())
        curves = _airmass(coords[None, :].transform_to(frame).alt.deg)  # (n_times, n_fields)
        ax.plot(hours, curves, color="#8a8a8a", lw=0.6, alpha=0.6, zorder=1)
        for o in obs:
            ax.plot([o.start / 3600.0, o.end / 3600.0], [o.airmass or np.nan] * 2,
                    color=FILTER_COLOURS.get(o.filter, "k"), lw=3.5, solid_capstyle="butt", zorder=3)
    shown = _draw_executed(ax, plan, executed)
    moon = _airmass(grid["moon_alt"])
    ax.plot(hours, moon, color="#c9a400", lw=1.6, ls=(0, (4, 2)), zorder=2)
    ax.set_ylim(AIRMASS_TOP, 1.0)
    _night_axis(ax, plan, hours, grid["sun_alt"])
    if fields:
        place_field_labels(ax, [(str(f), first[f].start / 3600.0, first[f].airmass or 1.0) for f in fields])
    ax.set_ylabel("airmass", fontsize=9)
    handles = [Line2D([], [], color="#8a8a8a", lw=0.8, label="planned field"),
               Line2D([], [], color="#c9a400", lw=1.6, ls=(0, (4, 2)),
                      label=f"Moon ({grid['moon_illumination']:.0%} lit)")]
    handles += [Line2D([], [], color=FILTER_COLOURS.get(f, "k"), lw=3.5, label=f"{f} exposure")
                for f in dict.fromkeys(o.filter for o in obs)]
    if shown:
        handles.append(Line2D([], [], color="k", marker="o", mfc="none", ls="none", label="executed before"))
    ax.legend(handles=handles, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=len(handles), fontsize=8,
              frameon=False)


#: Where a field's id may go around its first exposure (offset in points, alignment), in order of preference.
LABEL_PLACES = (((0, -9), "center", "top"), ((0, 6), "center", "bottom"), ((9, -2), "left", "center"),
                ((-9, -2), "right", "center"), ((0, -19), "center", "top"), ((0, 16), "center", "bottom"))


def place_field_labels(ax: Any, labels: Sequence[tuple[str, float, float]], fontsize: float = 6.5) -> None:
    """Each field's id beside its first exposure (hour, airmass), in the first place no earlier id takes.

    Boxes are estimated in points (a digit ~0.6 of the font size wide), on the axes' current limits.
    """
    scale = ax.figure.dpi / 72.0
    placed: list[tuple[float, float, float, float]] = []
    for text, hour, airmass in sorted(labels, key=lambda item: item[1]):
        x0, y0 = ax.transData.transform((hour, airmass)) / scale  # points
        w, h = 0.62 * fontsize * len(text) + 1.0, fontsize + 1.0
        choice = LABEL_PLACES[0]
        for place in LABEL_PLACES:
            box = _label_box(x0, y0, w, h, *place)
            if not any(_overlap(box, other) for other in placed):
                choice = place
                break
        placed.append(_label_box(x0, y0, w, h, *choice))
        (dx, dy), ha, va = choice
        ax.annotate(text, (hour, airmass), xytext=(dx, dy), textcoords="offset points", fontsize=fontsize,
                    ha=ha, va=va, color="#222", zorder=4)


def _label_box(x: float, y: float, w: float, h: float, offset: tuple[float, float], ha: str,
               va: str) -> tuple[float, float, float, float]:
    """(left, bottom, right, top) in points of a label at ``(x, y)`` + ``offset`` aligned by ``ha``/``va``."""
    x, y = x + offset[0], y + offset[1]
    left = {"left": x, "center": x - w / 2, "right": x - w}[ha]
    bottom = {"bottom": y, "center": y - h / 2, "top": y - h}[va]
    return left, bottom, left + w, bottom + h


def _overlap(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _dark_span(hours: np.ndarray, dark: np.ndarray, busy: Sequence[float]) -> tuple[float, float]:
    """Hours of the dark stretches (Sun below the horizon) holding an exposure (the longest without any)."""
    edges = np.flatnonzero(np.diff(np.r_[0, dark.astype(int), 0]))
    runs = [(float(hours[a]), float(hours[b - 1])) for a, b in zip(edges[::2], edges[1::2])]
    kept = [r for r in runs if any(r[0] - 0.25 <= h <= r[1] + 0.25 for h in busy)]
    if not kept and runs:
        kept = [max(runs, key=lambda r: r[1] - r[0])]
    ends = [h for r in kept for h in r] + list(busy)
    return (min(ends), max(ends)) if ends else (0.0, float(hours[-1]))


def _night_axis(ax: Any, plan: Any, hours: np.ndarray, sun_alt: np.ndarray) -> None:
    """The x axis on the night of the exposures (its dark hours, Sun below the horizon), ticks on the UTC hours."""
    from astropy import units as u

    busy = [o.start / 3600.0 for o in plan.observations] + [o.end / 3600.0 for o in plan.observations]
    lo, hi = _dark_span(hours, sun_alt < 0, busy)
    lo, hi = max(lo - 0.5, 0.0), min(hi + 0.5, float(hours[-1]))
    ax.set_xlim(lo, hi)
    past = (plan.start.utc.datetime.minute * 60 + plan.start.utc.datetime.second) / 3600.0  # into its UTC hour
    first = np.ceil(lo + past) - past
    ticks = np.arange(first, hi + 1e-9, 1.0 if hi - lo <= 14 else 2.0)
    ax.set_xticks(ticks, [(plan.start + t * u.hour).utc.isot[11:16] for t in ticks], fontsize=8)
    ax.set_xlabel("UTC", fontsize=8, labelpad=1)


def _draw_executed(ax: Any, plan: Any, executed: Sequence[Any]) -> int:
    """Executed exposures inside the horizon, hollow, at their airmass (computed here); how many were drawn.

    Those before the plan's start (a re-plan starts after them) are on the sky panels only.
    """
    span = float((plan.end - plan.start).to_value("s"))
    inside = [e for e in executed if 0.0 <= float((e.start - plan.start).to_value("s")) <= span]
    if not inside:
        return 0
    from astropy import units as u
    from astropy.coordinates import AltAz, SkyCoord

    from .scheduler_core.sky.fields import load_ztf_fields
    from .scheduler_core.sky.visibility import site

    grid = load_ztf_fields()
    rows = grid.index_of(np.array([e.field_id for e in inside]))
    times = [e.start for e in inside]
    from astropy.time import Time

    t = Time(times)
    alt = SkyCoord(grid.ra[rows] * u.deg, grid.dec[rows] * u.deg).transform_to(
        AltAz(obstime=t, location=site())).alt.deg
    hours = (t - plan.start).to_value("hour")
    for h, x, e in zip(hours, _airmass(alt), inside):
        ax.plot([h], [x], marker="o", ms=5, mfc="none", mec=FILTER_COLOURS.get(e.filter, "k"), mew=1.2, zorder=3)
    return len(inside)
