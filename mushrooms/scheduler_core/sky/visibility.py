"""When each ZTF field can be observed from Palomar over the planning horizon.

Constraints (all in :class:`~.config.PlanningConfig`): Sun below
``sun_alt_max_deg``; airmass (sec z) at most ``airmass_max``; |hour angle| at
most ``ha_max_h``; the P48 mount's southern keep-out zones; Moon separation
at least ``moon_sep_min_deg``.

Each constraint is a composable piece of :mod:`.constraints` (combined with
``&``; :func:`ztf_constraints`), reading the geometry of all fields and grid
times computed at once (:func:`~.constraints.observing_geometry`).  A window is a run of consecutive grid times
at which every constraint holds: between two grid times the altitude, hour
angle and Sun altitude are monotonic or convex enough that the constraints
also hold in between, so windows are slightly conservative (by less than one
grid step at each end), never optimistic.

The grid times are whole steps from a fixed epoch, :data:`GRID_ANCHOR` (local
mean noon at Palomar), and the apparent places of each *night* (the 24 h from
one local noon to the next) are taken at that night's middle.  So the
windows of a field do not depend on when the horizon starts or on which
other fields are computed with it: a cache of the whole grid per night (the
daemon's) gives exactly the windows computed here for one alert, and the
same inputs give the same plan whichever path made it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np
from astropy import units as u
from astropy.coordinates import EarthLocation
from astropy.time import Time, TimeDelta

from ..config import PlanningConfig
from .constraints import (AirmassBelow, Constraint, MoonSeparation, MountLimits, SunBelow,
                          observing_geometry)
from .ephemeris import GRID_ANCHOR
from .windows import Windows

__all__ = ["site", "observability_windows", "observing_conditions", "windows_from_mask", "ztf_constraints", "keep_out_boxes", "PALOMAR",
           "GRID_ANCHOR", "NIGHT_S", "ConstraintMasks", "constraint_masks", "night_steps", "night_epoch", "grid_times", "windows_on_grid"]

# GRID_ANCHOR (re-exported from .ephemeris): local mean noon at Palomar (lon -116.86 deg) on 2000-01-01; grid
# times are it plus whole time steps, and nights run from one such noon to the next.

#: Length of a night block (s).
NIGHT_S = 86400.0

#: P48 at Palomar (ztf_sim's coordinates): lat, lon (deg), height (m).
PALOMAR = (33.35728, -116.85986, 1707.0)


@functools.lru_cache(maxsize=8)
def site(telescope: str = "ztf") -> EarthLocation:
    """The location of the P48 (``"ztf"``, the default) or of the telescope a ``telescopes`` entry names."""
    if telescope == "ztf":
        lat, lon, height = PALOMAR
    else:
        from ..instruments.active import site_tuple
        from ..instruments.loader import load_description

        lat, lon, height = site_tuple(load_description(telescope))
    return EarthLocation.from_geodetic(lon=lon * u.deg, lat=lat * u.deg, height=height * u.m)


def _runs(ok: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row, first, last) index of every run of True along axis 1."""
    padded = np.zeros((ok.shape[0], ok.shape[1] + 2), dtype=np.int8)
    padded[:, 1:-1] = ok
    d = np.diff(padded, axis=1)
    r0, c0 = np.nonzero(d == 1)
    r1, c1 = np.nonzero(d == -1)
    return r0, c0, c1 - 1  # nonzero() is row-major, so starts and ends pair up


@dataclass(frozen=True)
class ConstraintMasks:
    """The observing constraints one by one, for fields x grid times.

    Attributes
    ----------
    night : numpy.ndarray
        (m,) bool: the Sun is below ``sun_alt_max_deg``.
    reachable : numpy.ndarray
        (n, m) bool: airmass at most ``airmass_max`` and inside the P48
        mount's hour-angle and keep-out limits.
    moon_clear : numpy.ndarray
        (n, m) bool: at least ``moon_sep_min_deg`` from the Moon.
    """

    night: np.ndarray
    reachable: np.ndarray
    moon_clear: np.ndarray

    def all(self) -> np.ndarray:
        """(n, m) bool: every constraint holds."""
        return self.night[None, :] & self.reachable & self.moon_clear


def constraint_masks(
    ra_deg: np.ndarray,
    dec_deg: np.ndarray,
    times: Time,
    config: PlanningConfig = PlanningConfig(),
    apparent_epoch: Time | None = None,
) -> ConstraintMasks:
    """Each observing constraint for fields x grid times (see :func:`observing_conditions`).

    Parameters
    ----------
    ra_deg, dec_deg : numpy.ndarray
        (n,) field centres (deg, ICRS).
    times : astropy.time.Time
        (m,) grid times (UTC).
    config : PlanningConfig
        Constraints (Sun, airmass, hour angle and keep-outs, Moon).
    apparent_epoch : astropy.time.Time, optional
        Epoch of the apparent (true equator and equinox of date) field
        places; default the middle of ``times``.  Over a day the places
        move by well under an arcsecond.

    Returns
    -------
    ConstraintMasks
    """
    geometry = observing_geometry(ra_deg, dec_deg, times, site(config.telescope), apparent_epoch)
    night, reachable, moon_clear = ztf_constraints(config)
    return ConstraintMasks(night=night(geometry)[0], reachable=reachable(geometry), moon_clear=moon_clear(geometry))


def ztf_constraints(config: PlanningConfig) -> tuple[Constraint, Constraint, Constraint]:
    """The scheduler's constraints: (night, reachable, Moon clear), composable with ``&``.

    Night: Sun below ``sun_alt_max_deg``; reachable: airmass at most
    ``airmass_max`` and inside the P48 mount's limits (``ha_max_h`` and the
    keep-out zones); Moon clear: at least ``moon_sep_min_deg`` from the Moon.
    """
    return (SunBelow(config.sun_alt_max_deg),
            AirmassBelow(config.airmass_max) & MountLimits(config.ha_max_h, keep_out_boxes(config)),
            MoonSeparation(config.moon_sep_min_deg))


def keep_out_boxes(config: PlanningConfig) -> tuple[tuple[float, float, float, float], ...] | None:
    """The mount's keep-out boxes (I4) of the telescope ``config`` plans; None for the P48 (its own rules)."""
    if config.telescope == "ztf":
        return None
    from ..instruments.loader import load_description

    return tuple((b.ha_min_deg, b.ha_max_deg, b.dec_min_deg, b.dec_max_deg)
                 for b in load_description(config.telescope).limits.keep_out)


def observing_conditions(
    ra_deg: np.ndarray,
    dec_deg: np.ndarray,
    times: Time,
    config: PlanningConfig = PlanningConfig(),
    apparent_epoch: Time | None = None,
) -> np.ndarray:
    """Where every observing constraint holds, for fields x grid times.

    A pure function of the field centres and the times: the daemon calls it
    once per night for the whole ZTF grid and reuses the result for every
    alert of that night (see :func:`windows_from_mask`).  The constraints one
    by one: :func:`constraint_masks`.

    Parameters
    ----------
    ra_deg, dec_deg : numpy.ndarray
        (n,) field centres (deg, ICRS).
    times : astropy.time.Time
        (m,) grid times (UTC).
    config : PlanningConfig
        Constraints (Sun, airmass, hour angle and keep-outs, Moon).
    apparent_epoch : astropy.time.Time, optional
        Epoch of the apparent field places; default the middle of ``times``.

    Returns
    -------
    numpy.ndarray
        (n, m) bool: True where the field can be observed at that time.
    """
    return constraint_masks(ra_deg, dec_deg, times, config, apparent_epoch).all()


def windows_from_mask(field_ids: np.ndarray, ok: np.ndarray, offsets_s: np.ndarray, exposure_s: float) -> Windows:
    """Windows from an observability mask on a time grid.

    Parameters
    ----------
    field_ids : numpy.ndarray
        (n,) field IDs, the rows of ``ok``.
    ok : numpy.ndarray
        (n, m) bool from :func:`observing_conditions`.
    offsets_s : numpy.ndarray
        (m,) grid times (s since the horizon start), increasing.
    exposure_s : float
        Windows shorter than this (s) are dropped.

    Returns
    -------
    Windows
        One row per run of consecutive True grid times.
    """
    field_ids = np.asarray(field_ids)
    offsets_s = np.asarray(offsets_s, float)
    rows, first, last = _runs(ok)
    w_start = offsets_s[first]
    w_end = offsets_s[last]
    keep = (w_end - w_start) >= exposure_s
    return Windows(field_ids=field_ids[rows[keep]], start=w_start[keep], end=w_end[keep])


def night_steps(step_s: float, night: int) -> np.ndarray:
    """Grid indices j (times ``GRID_ANCHOR + j * step_s``) that fall in one night.

    Parameters
    ----------
    step_s : float
        Grid step (s).
    night : int
        Nights since :data:`GRID_ANCHOR` (night 0 starts at it).
    """
    j0 = int(np.ceil(night * NIGHT_S / step_s - 1e-9))
    j1 = int(np.ceil((night + 1) * NIGHT_S / step_s - 1e-9))
    return np.arange(j0, j1, dtype=np.int64)


def night_epoch(night: int) -> Time:
    """The middle of a night: the epoch of its apparent places."""
    return GRID_ANCHOR + TimeDelta((night + 0.5) * NIGHT_S, format="sec")


def grid_times(j: np.ndarray, step_s: float) -> Time:
    """The UTC times of grid indices ``j``."""
    return GRID_ANCHOR + TimeDelta(np.asarray(j, dtype=np.int64) * step_s, format="sec")


def windows_on_grid(field_ids: np.ndarray, start: Time, config: PlanningConfig,
                    conditions: Callable[[int, np.ndarray], np.ndarray]) -> Windows:
    """Windows over ``[start, start + horizon]`` from observability on the anchored grid.

    Parameters
    ----------
    field_ids : numpy.ndarray
        (n,) field IDs.
    start : astropy.time.Time
        Horizon start (UTC).
    config : PlanningConfig
        Horizon, grid step and exposure.
    conditions : callable
        ``conditions(night, j) -> (n, len(j))`` bool: every constraint at the
        grid indices ``j`` of that night (apparent places at
        :func:`night_epoch`).

    Returns
    -------
    Windows
        Times in s since ``start``.
    """
    step = float(config.time_step_s)
    t_start = float((start - GRID_ANCHOR).sec)
    j_first = int(np.ceil(t_start / step - 1e-9))
    j_last = int(np.floor((t_start + config.horizon_s) / step + 1e-9))
    parts, js = [], []
    for night in range(int(np.floor(j_first * step / NIGHT_S)), int(np.floor(j_last * step / NIGHT_S)) + 1):
        j = night_steps(step, night)
        j = j[(j >= j_first) & (j <= j_last)]
        if j.size:
            parts.append(conditions(night, j))
            js.append(j)
    ok = np.concatenate(parts, axis=1)
    offsets = np.concatenate(js) * step - t_start
    return windows_from_mask(field_ids, ok, offsets, config.exposure_s)


def observability_windows(
    field_ids: np.ndarray,
    ra_deg: np.ndarray,
    dec_deg: np.ndarray,
    start: Time,
    config: PlanningConfig = PlanningConfig(),
) -> Windows:
    """Observability windows of fields over ``[start, start + horizon]``.

    Parameters
    ----------
    field_ids : numpy.ndarray
        Field IDs.
    ra_deg, dec_deg : numpy.ndarray
        Field centres (deg, ICRS).
    start : astropy.time.Time
        Horizon start (UTC).
    config : PlanningConfig
        Horizon, grid step and constraints.

    Returns
    -------
    Windows
        One row per window (s since ``start``); windows shorter than one
        exposure are dropped.
    """
    def conditions(night: int, j: np.ndarray) -> np.ndarray:
        return observing_conditions(ra_deg, dec_deg, grid_times(j, config.time_step_s), config,
                                    apparent_epoch=night_epoch(night))

    return windows_on_grid(np.asarray(field_ids), start, config, conditions)
