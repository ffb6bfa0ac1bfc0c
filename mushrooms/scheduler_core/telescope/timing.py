"""The P48's overheads between two exposures, as ZTF's scheduler charges them.

Follows ztf_sim (``ZwickyTransientFacility/ztf_sim``, commit c5ab409,
BSD-3-Clause licence; read, not copied): ``TelescopeStateMachine`` changes
the filter first (``process_filter_change``: ``FILTER_CHANGE_TIME`` = 135 s
when the filter differs) and then slews (``process_slew``), the slew lasting
the longest of the readout (``READOUT_TIME`` = 8 s, read out during the
slew) and the hour-angle, declination and dome-azimuth axes' trapezoidal
moves (``constants.slew_time``, each plus ``SETTLE_TIME`` = 1 s when it
moves).  So a filter change adds to the slew (Q7)::

    overhead = [filter differs] * t_filter + max(t_readout, t_ha, t_dec, t_dome)

The hour-angle and declination drive parameters are the planner's
:class:`~..config.SlewModel` (ztf_sim's ``P48_slew_pars``); the dome's are
ztf_sim's (0.5 deg s^-2, 3 deg s^-1).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from ..config import SlewModel
from .rules import QueueRules
from .slew import axis_time

__all__ = ["TelescopeTiming", "exposure_overhead_s", "dome_azimuth_deg", "PALOMAR_LAT_DEG"]

#: Latitude of the P48 (deg), ztf_sim's ``P48_loc``.
PALOMAR_LAT_DEG = 33.35728


@dataclass(frozen=True)
class TelescopeTiming:
    """What the telescope takes to get from one exposure to the next, and the scheduler's limits.

    Attributes
    ----------
    slew : SlewModel
        Hour-angle and declination axes, settle and readout (s).
    dome_accel_deg_s2, dome_vmax_deg_s : float
        Dome azimuth axis (ztf_sim: 0.5 deg s^-2, 3 deg s^-1).
    filter_change_s : float
        Filter exchange (s), before the slew (ztf_sim ``FILTER_CHANGE_TIME`` = 135 s).
    max_airmass : float
        A queue target's ``max_airmass`` when it gives none (ztf_sim ``MAX_AIRMASS``).
    ha_max_h : float
        Largest |hour angle| ``_next_obs`` takes (h).
    sun_alt_max_deg : float
        The telescope observes with the Sun below this (deg; ztf_sim 12-degree twilight).
    survey_step_s : float
        What the survey takes when no ToO target is observable: one exposure
        (ztf_sim ``TelescopeStateMachine.wait`` = ``EXPOSURE_TIME``, 30 s) plus its readout.
    lost_pointing_slew_s : float
        Slew (s) charged after the survey had the telescope (where it pointed is unknown).
    rules : QueueRules
        How the scheduler switches queues and treats a target it cannot
        slew to (:mod:`.rules`; default ztf_sim's main loop).
    """

    slew: SlewModel = field(default_factory=SlewModel)
    dome_accel_deg_s2: float = 0.5
    dome_vmax_deg_s: float = 3.0
    filter_change_s: float = 135.0
    max_airmass: float = 2.5
    ha_max_h: float = 5.95
    sun_alt_max_deg: float = -12.0
    survey_step_s: float = 38.0
    lost_pointing_slew_s: float = 20.0
    rules: QueueRules = field(default_factory=QueueRules)

    def __post_init__(self) -> None:
        for name in ("dome_accel_deg_s2", "dome_vmax_deg_s", "survey_step_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in ("filter_change_s", "lost_pointing_slew_s"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    def with_switch(self, switch: str) -> "TelescopeTiming":
        """The same telescope, its scheduler switching to the ``switch`` (``first`` or ``last``) valid queue (Q1)."""
        return replace(self, rules=replace(self.rules, switch=switch))

    def scaled(self, factor: float) -> "TelescopeTiming":
        """The same telescope ``factor`` times slower (> 1) or faster (< 1) in every overhead."""
        s = self.slew
        slew = SlewModel(ha_accel_deg_s2=s.ha_accel_deg_s2 / factor**2, ha_vmax_deg_s=s.ha_vmax_deg_s / factor,
                         dec_accel_deg_s2=s.dec_accel_deg_s2 / factor**2, dec_vmax_deg_s=s.dec_vmax_deg_s / factor,
                         settle_s=s.settle_s * factor, readout_s=s.readout_s * factor)
        return TelescopeTiming(slew=slew, dome_accel_deg_s2=self.dome_accel_deg_s2 / factor**2,
                               dome_vmax_deg_s=self.dome_vmax_deg_s / factor,
                               filter_change_s=self.filter_change_s * factor, max_airmass=self.max_airmass,
                               ha_max_h=self.ha_max_h, sun_alt_max_deg=self.sun_alt_max_deg,
                               survey_step_s=self.survey_step_s,
                               lost_pointing_slew_s=self.lost_pointing_slew_s * factor, rules=self.rules)


def dome_azimuth_deg(ha_deg: ArrayLike, dec_deg: ArrayLike, lat_deg: float = PALOMAR_LAT_DEG) -> np.ndarray:
    """Azimuth (deg, from north through east, [0, 360)) of a pointing at hour angle ``ha_deg``."""
    h, d, phi = np.radians(np.asarray(ha_deg, float)), np.radians(np.asarray(dec_deg, float)), np.radians(lat_deg)
    az = np.arctan2(-np.cos(d) * np.sin(h), np.sin(d) * np.cos(phi) - np.cos(d) * np.cos(h) * np.sin(phi))
    return np.degrees(az) % 360.0


def _wrapped(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    d = np.abs(np.asarray(b, float) - np.asarray(a, float)) % 360.0
    return np.minimum(d, 360.0 - d)


def exposure_overhead_s(ha1_deg: ArrayLike, dec1_deg: ArrayLike, az1_deg: ArrayLike, ha2_deg: ArrayLike,
                        dec2_deg: ArrayLike, az2_deg: ArrayLike, filter_changes: ArrayLike,
                        timing: TelescopeTiming = TelescopeTiming()) -> np.ndarray:
    """Time (s) from the end of one exposure to the start of the next (Q7; broadcasts).

    Parameters
    ----------
    ha1_deg, dec1_deg, az1_deg : array_like
        Where the telescope points at the end of the previous exposure
        (hour angle, declination, dome azimuth; deg).
    ha2_deg, dec2_deg, az2_deg : array_like
        The next target at the moment the slew starts (deg).
    filter_changes : array_like of bool
        The next exposure is in another filter.
    timing : TelescopeTiming
        Axis parameters, settle, readout and filter change.

    Returns
    -------
    numpy.ndarray
        Filter change (when one) plus the longest of the readout and the
        three axes' slews (each with the settle when it moves).
    """
    s = timing.slew
    axes = [axis_time(_wrapped(ha1_deg, ha2_deg), s.ha_accel_deg_s2, s.ha_vmax_deg_s),
            axis_time(np.asarray(dec2_deg, float) - np.asarray(dec1_deg, float), s.dec_accel_deg_s2,
                      s.dec_vmax_deg_s),
            axis_time(_wrapped(az1_deg, az2_deg), timing.dome_accel_deg_s2, timing.dome_vmax_deg_s)]
    slew = np.maximum.reduce([np.where(a > 0, a + s.settle_s, 0.0) for a in axes])
    change = np.where(np.asarray(filter_changes, bool), timing.filter_change_s, 0.0)
    return change + np.maximum(slew, s.readout_s)
