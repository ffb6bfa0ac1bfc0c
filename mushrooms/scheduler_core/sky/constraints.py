"""Observing constraints as small composable pieces, each a boolean mask over fields x times.

The sky's geometry for ``n`` fields and ``m`` grid times is computed once
(:func:`observing_geometry`: Sun altitude, hour angles, airmasses, Moon
separations, all vectorised); each constraint then reads it and returns a
boolean array that broadcasts to ``(n, m)``.  Constraints combine with ``&``
(m4opt's pattern)::

    geometry = observing_geometry(ra, dec, times, site())
    night = SunBelow(-18.0)
    reachable = AirmassBelow(2.5) & MountLimits(ha_max_h=5.95)
    ok = (night & reachable & MoonSeparation(20.0))(geometry)   # (n, m) bool

The ZTF scheduler's constraints, from its
:class:`~mushrooms.scheduler_core.config.PlanningConfig`:
:func:`~.visibility.ztf_constraints`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from astropy import units as u
from astropy.coordinates import TETE, EarthLocation, SkyCoord
from astropy.time import Time

from .ephemeris import ephemeris

__all__ = [
    "ObservingGeometry", "observing_geometry", "Constraint", "AllOf", "SunBelow", "AirmassBelow",
    "MountLimits", "MoonSeparation", "mount_limits_ok", "pointing_ok",
]


@dataclass(frozen=True)
class ObservingGeometry:
    """Where the fields, the Sun and the Moon are, for n fields x m grid times.

    Attributes
    ----------
    sun_alt_deg : numpy.ndarray
        (m,) Sun altitude (deg).
    ha_deg : numpy.ndarray
        (n, m) hour angle of the fields' apparent places (deg, in [-180, 180)).
    dec_deg : numpy.ndarray
        (n,) field declinations (deg, ICRS).
    airmass : numpy.ndarray
        (n, m) sec z; ``inf`` below the horizon.
    moon_sep_deg : numpy.ndarray
        (n, m) angular distance to the Moon (deg).
    """

    sun_alt_deg: np.ndarray
    ha_deg: np.ndarray
    dec_deg: np.ndarray
    airmass: np.ndarray
    moon_sep_deg: np.ndarray


def observing_geometry(
    ra_deg: np.ndarray,
    dec_deg: np.ndarray,
    times: Time,
    location: EarthLocation,
    apparent_epoch: Time | None = None,
) -> ObservingGeometry:
    """The geometry every constraint reads, for all fields and grid times at once.

    The Sun, the Moon and the local apparent sidereal time come from astropy
    at the ephemeris nodes, interpolated to the grid (:mod:`.ephemeris`,
    E1-E3); field altitudes and hour angles then follow in closed
    form from the fields' apparent (true equator and equinox of date) places.

    Parameters
    ----------
    ra_deg, dec_deg : numpy.ndarray
        (n,) field centres (deg, ICRS).
    times : astropy.time.Time
        (m,) grid times (UTC).
    location : astropy.coordinates.EarthLocation
        The telescope.
    apparent_epoch : astropy.time.Time, optional
        Epoch of the apparent field places; default the middle of ``times``.
        Over a day the places move by well under an arcsecond.

    Returns
    -------
    ObservingGeometry
    """
    lat = np.radians(location.lat.deg)
    ra_deg = np.asarray(ra_deg, float)
    dec_deg = np.asarray(dec_deg, float)

    # Sun, Moon and sidereal time: astropy every EPHEMERIS_STEP_S, interpolated (E1-E3), not one per field
    sky = ephemeris(times, location)
    sun_alt, lst = sky.sun_alt_deg, sky.lst_deg

    # Fields: apparent place of date (precession, nutation, aberration) once
    if apparent_epoch is None:
        apparent_epoch = times[0] + (times[-1] - times[0]) * 0.5
    app = SkyCoord(ra=ra_deg * u.deg, dec=dec_deg * u.deg, frame="icrs").transform_to(TETE(obstime=apparent_epoch))
    ra_app = app.ra.deg[:, None]
    dec_app = np.radians(app.dec.deg)[:, None]
    ha = (lst[None, :] - ra_app + 180.0) % 360.0 - 180.0
    sin_alt = np.sin(lat) * np.sin(dec_app) + np.cos(lat) * np.cos(dec_app) * np.cos(np.radians(ha))
    with np.errstate(divide="ignore"):
        airmass = np.where(sin_alt > 0, 1.0 / np.where(sin_alt > 0, sin_alt, 1.0), np.inf)

    moon_ra = np.radians(sky.moon_ra_deg)[None, :]
    moon_dec = np.radians(sky.moon_dec_deg)[None, :]
    fra = np.radians(ra_deg)[:, None]
    fdec = np.radians(dec_deg)[:, None]
    cos_sep = np.sin(fdec) * np.sin(moon_dec) + np.cos(fdec) * np.cos(moon_dec) * np.cos(fra - moon_ra)
    moon_sep = np.degrees(np.arccos(np.clip(cos_sep, -1, 1)))
    return ObservingGeometry(sun_alt_deg=sun_alt, ha_deg=ha, dec_deg=dec_deg, airmass=airmass,
                             moon_sep_deg=moon_sep)


class Constraint:
    """One observing constraint: ``constraint(geometry)`` is a bool array broadcasting to (n, m).

    ``a & b`` is the constraint that both hold.
    """

    def __call__(self, geometry: ObservingGeometry) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def __and__(self, other: "Constraint") -> "AllOf":
        mine = self.parts if isinstance(self, AllOf) else (self,)
        theirs = other.parts if isinstance(other, AllOf) else (other,)
        return AllOf(mine + theirs)


@dataclass(frozen=True)
class AllOf(Constraint):
    """Every one of ``parts`` holds (the ``&`` of constraints), evaluated left to right."""

    parts: tuple[Constraint, ...]

    def __call__(self, geometry: ObservingGeometry) -> np.ndarray:
        return functools.reduce(np.logical_and, (c(geometry) for c in self.parts))


@dataclass(frozen=True)
class SunBelow(Constraint):
    """Night: the Sun at most ``alt_deg`` (deg) high; a (1, m) mask."""

    alt_deg: float

    def __call__(self, geometry: ObservingGeometry) -> np.ndarray:
        return (geometry.sun_alt_deg <= self.alt_deg)[None, :]


@dataclass(frozen=True)
class AirmassBelow(Constraint):
    """Airmass (sec z) at most ``max_airmass``; an (n, m) mask (False below the horizon)."""

    max_airmass: float

    def __call__(self, geometry: ObservingGeometry) -> np.ndarray:
        return geometry.airmass <= self.max_airmass


@dataclass(frozen=True)
class MountLimits(Constraint):
    """The mount can point there: |hour angle| at most ``ha_max_h`` and the keep-out zones.

    ``keep_out`` None: the P48's (:func:`mount_limits_ok`); else a telescope's
    open (HA, Dec) boxes ``(ha_min, ha_max, dec_min, dec_max)`` (deg, I4).
    """

    ha_max_h: float
    keep_out: tuple[tuple[float, float, float, float], ...] | None = None

    def __call__(self, geometry: ObservingGeometry) -> np.ndarray:
        return self.allows(geometry.ha_deg, geometry.dec_deg[:, None])

    def allows(self, ha_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
        """The mount reaches (HA, Dec) (deg; broadcast)."""
        if self.keep_out is None:
            return mount_limits_ok(ha_deg, dec_deg, self.ha_max_h)
        return pointing_ok(ha_deg, dec_deg, self.ha_max_h, self.keep_out)


@dataclass(frozen=True)
class MoonSeparation(Constraint):
    """At least ``min_deg`` (deg) from the Moon; an (n, m) mask."""

    min_deg: float

    def __call__(self, geometry: ObservingGeometry) -> np.ndarray:
        return geometry.moon_sep_deg >= self.min_deg


def pointing_ok(ha_deg: np.ndarray, dec_deg: np.ndarray, ha_max_h: float,
                keep_out: tuple[tuple[float, float, float, float], ...]) -> np.ndarray:
    """(I4) |HA| at most ``ha_max_h`` (h) and outside every open box ``(ha_min, ha_max, dec_min, dec_max)`` (deg)."""
    ha = np.asarray(ha_deg, float)
    dec = np.asarray(dec_deg, float)
    ok = np.abs(ha) <= ha_max_h * 15.0
    for ha_lo, ha_hi, dec_lo, dec_hi in keep_out:
        ok = ok & ~((ha > ha_lo) & (ha < ha_hi) & (dec > dec_lo) & (dec < dec_hi))
    return ok


def mount_limits_ok(ha_deg: np.ndarray, dec_deg: np.ndarray, ha_max_h: float) -> np.ndarray:
    """P48 pointing limits: hour angle and the southern keep-out zones.

    Parameters
    ----------
    ha_deg : numpy.ndarray
        Hour angle (deg, wrapped to [-180, 180)).
    dec_deg : numpy.ndarray
        Declination (deg); broadcasts against ``ha_deg``.
    ha_max_h : float
        Largest |hour angle| (hours).

    Returns
    -------
    numpy.ndarray
        True where the mount can point.  Besides |HA| <= ha_max_h: rising
        fields (HA < -17.6 deg) need Dec >= -22 deg, setting ones Dec >= -45
        deg, and away from the meridian (|HA| > 3 deg) Dec >= -46 deg
        (ZTF's queue limits as documented for ztf_sim).
    """
    ha = np.asarray(ha_deg, float)
    dec = np.asarray(dec_deg, float)
    ok = np.abs(ha) <= ha_max_h * 15.0
    ok &= (ha >= -17.6) | (dec >= -22.0)
    ok &= (ha <= -17.6) | (dec >= -45.0)
    ok &= (np.abs(ha) <= 3.0) | (dec >= -46.0)
    ok &= dec <= 87.5
    return ok
