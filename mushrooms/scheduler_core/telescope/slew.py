"""Slew times of the P48 between ZTF fields (per-axis trapezoid).

The mount is equatorial: it moves in hour angle and declination at the same
time, so a slew takes as long as the slower axis.  Between two fields visited
one after the other the hour-angle travel equals the right-ascension
difference (the sidereal drift during the slew itself is a fraction of a
degree and is ignored), which makes slew times independent of the clock.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..config import SlewModel

__all__ = ["axis_time", "slew_time", "overhead_time", "slew_matrix"]


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
) -> np.ndarray:
    """Mount slew time (s), settle included, between pointings (broadcasts).

    Parameters
    ----------
    ra1_deg, dec1_deg, ra2_deg, dec2_deg : array_like
        Field centres (deg).
    model : SlewModel
        Axis parameters.

    Returns
    -------
    numpy.ndarray
        Slew time (s); zero for no motion.
    """
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

    Returns
    -------
    numpy.ndarray
        Overhead (s).
    """
    slew = slew_time(ra1_deg, dec1_deg, ra2_deg, dec2_deg, model)
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
