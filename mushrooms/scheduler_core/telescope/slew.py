"""Slew times of the P48 between ZTF fields (per-axis trapezoid).

The mount is equatorial: it moves in hour angle and declination at the same
time, so a slew takes as long as the slower axis.  Between two fields visited
one after the other the hour-angle travel equals the right-ascension
difference (the sidereal drift during the slew itself is a fraction of a
degree and is ignored), which makes slew times independent of the clock.

(M1) An alt-azimuth mount (WINTER: a description whose axes are ``azimuth``
and ``altitude``, ``docs/design/telescopes.md``) moves in azimuth and
altitude: its travel depends on where the two fields stand at the slew's
time ``t``, so :func:`slew_time` takes an :class:`AltAzMount` and ``t``
(s from the horizon's start).  The ``SlewModel``'s ``ha_*`` terms drive the
azimuth axis and its ``dec_*`` terms the altitude axis
(``instruments/defaults.py``); the azimuth travel is the shorter way round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..config import SlewModel

__all__ = ["axis_time", "slew_time", "overhead_time", "slew_matrix", "AltAzMount", "SIDEREAL_DEG_PER_S"]

#: (M1) Local sidereal time gained per second of time (deg s^-1).
SIDEREAL_DEG_PER_S = 360.98564736629 / 86400.0


@dataclass(frozen=True)
class AltAzMount:
    """(M1) An alt-azimuth mount at a site, and the sidereal time at the horizon's start.

    Attributes
    ----------
    latitude_deg : float
        Site latitude (deg).
    lst0_deg : float
        Local apparent sidereal time (deg) at ``t = 0``, the horizon's start.
    to_date : tuple of tuple of float, optional
        3 x 3 rotation from the fields' (ICRS) axes to the true equator and
        equinox of the start (precession-nutation, ``erfa.pnm06a``); None:
        the places are taken as of date.
    """

    latitude_deg: float
    lst0_deg: float
    to_date: tuple[tuple[float, float, float], ...] | None = None

    def alt_az(self, ra_deg: ArrayLike, dec_deg: ArrayLike, t_s: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Altitude and azimuth (deg; azimuth from north through east) of the positions at ``t_s`` (s)."""
        ra_deg, dec_deg = np.asarray(ra_deg, float), np.asarray(dec_deg, float)
        if self.to_date is not None:  # (M1) the places of date
            r, d = np.radians(ra_deg), np.radians(dec_deg)
            u = np.stack(np.broadcast_arrays(np.cos(d) * np.cos(r), np.cos(d) * np.sin(r), np.sin(d)), axis=-1)
            w = u @ np.asarray(self.to_date, float).T
            ra_deg = np.degrees(np.arctan2(w[..., 1], w[..., 0]))
            dec_deg = np.degrees(np.arcsin(np.clip(w[..., 2], -1.0, 1.0)))
        ha = np.radians(self.lst0_deg + SIDEREAL_DEG_PER_S * np.asarray(t_s, float) - ra_deg)
        dec, lat = np.radians(dec_deg), np.radians(self.latitude_deg)
        sin_alt = np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(ha)
        az = np.arctan2(-np.cos(dec) * np.sin(ha), np.sin(dec) * np.cos(lat) - np.cos(dec) * np.cos(ha) * np.sin(lat))
        return np.degrees(np.arcsin(np.clip(sin_alt, -1.0, 1.0))), np.degrees(az) % 360.0


def axis_time(distance_deg: ArrayLike, accel_deg_s2: float, vmax_deg_s: float) -> np.ndarray:
    """Time (s) for one axis to move ``distance_deg`` with a trapezoidal profile.

    Parameters
    ----------
    distance_deg : array_like
        Absolute travel (deg).
    accel_deg_s2 : float
        Acceleration and deceleration (deg s^-2).
    vmax_deg_s : float
        Top speed (deg s^-1).

    Returns
    -------
    numpy.ndarray
        Travel time (s): ``2 sqrt(d/a)`` when the axis never reaches top
        speed (``d < v^2/a``), else ``d/v + v/a``.
    """
    d = np.abs(np.asarray(distance_deg, dtype=float))
    triangular = d < vmax_deg_s**2 / accel_deg_s2
    return np.where(
        triangular,
        2.0 * np.sqrt(d / accel_deg_s2),
        d / vmax_deg_s + vmax_deg_s / accel_deg_s2,
    )


def _wrapped_dra(ra1_deg: ArrayLike, ra2_deg: ArrayLike) -> np.ndarray:
    dra = (np.asarray(ra2_deg, float) - np.asarray(ra1_deg, float) + 180.0) % 360.0 - 180.0
    return np.abs(dra)


def slew_time(
    ra1_deg: ArrayLike,
    dec1_deg: ArrayLike,
    ra2_deg: ArrayLike,
    dec2_deg: ArrayLike,
    model: SlewModel = SlewModel(),
    mount: AltAzMount | None = None,
    t_s: ArrayLike = 0.0,
) -> np.ndarray:
    """Mount slew time (s), settle included, between pointings (broadcasts).

    Parameters
    ----------
    ra1_deg, dec1_deg, ra2_deg, dec2_deg : array_like
        Field centres (deg).
    model : SlewModel
        Axis parameters.
    mount : AltAzMount, optional
        (M1) An alt-azimuth mount: the travel is in azimuth and altitude at
        ``t_s``; None (default): an equatorial mount, timed by the RA and
        Dec differences whatever the time.
    t_s : array_like
        With ``mount``: when the slew starts (s from the horizon's start).

    Returns
    -------
    numpy.ndarray
        Slew time (s); zero for no motion.
    """
    if mount is not None:  # (M1) azimuth (the shorter way) and altitude, at the slew's time
        alt1, az1 = mount.alt_az(ra1_deg, dec1_deg, t_s)
        alt2, az2 = mount.alt_az(ra2_deg, dec2_deg, t_s)
        t_az = axis_time(_wrapped_dra(az1, az2), model.ha_accel_deg_s2, model.ha_vmax_deg_s)
        t = np.maximum(t_az, axis_time(alt2 - alt1, model.dec_accel_deg_s2, model.dec_vmax_deg_s))
        return np.where(t > 0, t + model.settle_s, 0.0)
    t_ha = axis_time(_wrapped_dra(ra1_deg, ra2_deg), model.ha_accel_deg_s2, model.ha_vmax_deg_s)
    t_dec = axis_time(
        np.asarray(dec2_deg, float) - np.asarray(dec1_deg, float),
        model.dec_accel_deg_s2,
        model.dec_vmax_deg_s,
    )
    t = np.maximum(t_ha, t_dec)
    return np.where(t > 0, t + model.settle_s, 0.0)


def overhead_time(
    ra1_deg: ArrayLike,
    dec1_deg: ArrayLike,
    ra2_deg: ArrayLike,
    dec2_deg: ArrayLike,
    model: SlewModel = SlewModel(),
    filter_change_s: float | ArrayLike = 0.0,
    mount: AltAzMount | None = None,
    t_s: ArrayLike = 0.0,
) -> np.ndarray:
    """Least time (s) from the end of one exposure to the start of the next.

    The readout, the slew and a filter change all run in parallel, so the
    overhead is the longest of the three.

    Parameters
    ----------
    ra1_deg, dec1_deg, ra2_deg, dec2_deg : array_like
        Field centres (deg) of the two exposures.
    model : SlewModel
        Axis parameters and readout time.
    filter_change_s : float or array_like
        Filter exchange time (s) when the filter changes, else 0.
    mount, t_s : AltAzMount or None, array_like
        (M1) An alt-azimuth mount and the slew's time (:func:`slew_time`).

    Returns
    -------
    numpy.ndarray
        Overhead (s).
    """
    slew = slew_time(ra1_deg, dec1_deg, ra2_deg, dec2_deg, model, mount, t_s)
    return np.maximum(np.maximum(slew, model.readout_s), filter_change_s)


def slew_matrix(ra_deg: ArrayLike, dec_deg: ArrayLike, model: SlewModel = SlewModel()) -> np.ndarray:
    """Square matrix (s) of exposure-to-exposure overheads between fields.

    Parameters
    ----------
    ra_deg, dec_deg : array_like
        Field centres (deg), length n.
    model : SlewModel
        Axis parameters.

    Returns
    -------
    numpy.ndarray
        (n, n) overheads ``max(slew, readout)``; the diagonal is 0.
    """
    ra = np.asarray(ra_deg, float)
    dec = np.asarray(dec_deg, float)
    m = overhead_time(ra[:, None], dec[:, None], ra[None, :], dec[None, :], model)
    np.fill_diagonal(m, 0.0)
    return m
