"""The plan checker's own geometry: field grid, CCD footprints, site, mount, slews, Sun and Moon.

The checker shares no code with the schedulers' geometry (``fields``,
``visibility``, ``slew``), so a bug there cannot hide behind the same bug
here.  It has its own reading of the package data files, its own site, mount
and slew arithmetic from published constants, and its own footprint test:

* **Field grid and CCD layout**: parsed here from ``data/ZTF_Fields.txt``
  and ``data/ztf_ccd_layout.tbl`` (the files ``fields.py`` reads too; see
  ``data/SOURCES.md``).
* **Footprints**: each CCD is a spherical quadrilateral whose corners are
  the layout's plane offsets lifted onto the sphere around the field centre
  (a rotation matrix, not ``fields.deproject``); a pixel centre is covered
  when it lies on the inner side of all four great-circle edges of some CCD
  (the schedulers test straight edges in the projected plane; the two differ
  by about 1 arcsec, far below a pixel).
* **Site**: :data:`P48_SITE`, ztf_sim's GPS position of the P48.
* **Sun, Moon, field altitude and hour angle**: astropy (full ICRS to AltAz
  and true-equator-of-date transforms, Moon topocentric) evaluated on a
  coarse time grid (:data:`GRID_STEP_S`) spanning the plan, then interpolated
  to the start, middle and end of every exposure by cubic Lagrange
  polynomials through the four grid times around each (a few lines of
  numpy: no interpolation library to import).  The interpolated quantities
  (sin altitude, Moon direction, unwrapped hour angle) are smooth with
  periods of a day or more, so the error, about ``(h ω)⁴ / 40`` of their
  amplitude (h the step, ω the Earth's rotation rate), is below 1e-3 deg,
  far inside the checker's tolerances; the grid keeps the checker cheaper than
  the greedy scheduler it checks.
* **Mount limits**: :func:`mount_reachable`, ztf_sim's queue rules.
* **Slews**: :func:`slew_seconds`, the per-axis trapezoid written out from
  its kinematics, with the drive parameters of the plan's
  :class:`~.config.SlewModel` (the specification being checked against).
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass
from importlib import resources
from typing import Iterable

import erfa
import numpy as np
from astropy import units as u
from astropy.coordinates import AltAz, EarthLocation, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from ..config import SlewModel
from .check_telescope import CheckScope
from ..sky.healpix import hp

__all__ = ["P48_SITE", "GRID_STEP_S", "Conditions", "conditions", "field_positions", "polygon_coverage", "polygon_mask",
           "mount_reachable", "slew_seconds", "altaz_slew_seconds"]

#: P48 at Palomar: geodetic latitude, longitude (deg) and height (m), the GPS
#: position used by ZTF's robotic observing software as given in ztf_sim's
#: ``ztf_sim/constants.py`` (``P48_loc``: 33d21m26.2s, -116d51m35.5s, 1707 m;
#: commit 2208be2 "Change P48 position to GPS coordinates used by ROS").
P48_SITE = (33.0 + 21.0 / 60 + 26.2 / 3600, -(116.0 + 51.0 / 60 + 35.5 / 3600), 1707.0)

#: Spacing (s) of the time grid on which astropy is evaluated before the
#: cubic interpolation to the exposures' times.
GRID_STEP_S = 1800.0

_DATA = "data"


# --------------------------------------------------------------------------- data files

def _data_text(name: str) -> str:
    return resources.files("mushrooms.scheduler_core").joinpath(_DATA, name).read_text()


@functools.lru_cache(maxsize=1)
def field_positions() -> dict[int, tuple[float, float]]:
    """Field ID -> (RA, Dec) in deg, read from ``ZTF_Fields.txt``."""
    grid = {}
    for line in _data_text("ZTF_Fields.txt").splitlines():
        words = line.split()
        if words and not words[0].startswith("%"):
            grid[int(words[0])] = (float(words[1]), float(words[2]))
    return grid


@functools.lru_cache(maxsize=1)
def _ccd_offsets() -> np.ndarray:
    """(16, 4, 2) corner offsets (EW, NS; deg) of each CCD, from ``ztf_ccd_layout.tbl``."""
    corners: dict[int, list[tuple[float, float]]] = {}
    rows = csv.reader(_data_text("ztf_ccd_layout.tbl").splitlines()[1:])
    for ew, ns, ccd in rows:
        corners.setdefault(int(ccd), []).append((float(ew), float(ns)))
    return np.array([corners[k] for k in sorted(corners)], float)


def _unit(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], axis=-1)


def _ccd_vertices(ra0_deg: float, dec0_deg: float, offsets: np.ndarray | None = None) -> np.ndarray:
    """(16, 4, 3) unit vectors of the CCD corners of a field centred at (ra0, dec0).

    The layout's offsets (x, y) are orthographic plane coordinates: x grows
    to the West (``x = -cos(dec) sin(ra - ra0)``), y to the North, so a
    corner is ``x * west + y * north + sqrt(1 - x^2 - y^2) * centre``.
    """
    ra0 = np.radians(ra0_deg)
    centre = _unit(ra0_deg, dec0_deg)
    west = np.array([np.sin(ra0), -np.cos(ra0), 0.0])
    north = np.cross(centre, -west)
    basis = np.stack([west, north, centre])  # rows: the local axes
    xy = np.radians(_ccd_offsets() if offsets is None else offsets)
    local = np.concatenate([xy, np.sqrt(1.0 - (xy ** 2).sum(-1, keepdims=True))], axis=-1)
    return local @ basis


def _covered_pixels(ra0_deg: float, dec0_deg: float, nside: int, offsets: np.ndarray | None = None) -> np.ndarray:
    """NESTED pixels whose centres lie inside one of the field's 16 CCDs (or quadrilaterals ``offsets``)."""
    verts = _ccd_vertices(ra0_deg, dec0_deg, offsets)
    if not len(verts):
        return np.zeros(0, np.int64)
    centre = _unit(ra0_deg, dec0_deg)
    reach = float(np.arccos(np.clip(verts @ centre, -1, 1)).max()) + 1e-9
    cand = hp.query_disc(nside, centre, reach, inclusive=False, nest=True)
    pix = np.stack(hp.pix2vec(nside, cand, nest=True), axis=-1)  # (m, 3)
    normals = np.cross(verts, np.roll(verts, -1, axis=1))  # (16, 4, 3) edge planes
    inward = np.sign(np.einsum("ckj,cj->ck", normals, verts.mean(axis=1)))
    # a described camera's detectors may share edges (LS4's gapless mosaic): a pixel centre on one is on both,
    # whatever the rounding (ZTF's CCDs have gaps and keep the exact test)
    edge = 0.0 if offsets is None else -1e-12
    inner = (pix @ (normals * inward[..., None]).reshape(-1, 3).T) >= edge  # (m, 4 n): n CCDs x 4 edges
    # inside a CCD = its four edge bytes all 1: read each CCD's four bools as one uint32
    on_ccd = inner.reshape(-1, len(verts), 4).view(np.uint32)[..., 0] == 0x01010101
    return cand[on_ccd.any(axis=1)]


def polygon_coverage(field_ids: Iterable[int], prob: np.ndarray, without: Iterable[int] = (),
                     scope: CheckScope | None = None) -> float:
    """Probability whose pixel centres fall inside the fields' CCD outlines.

    Parameters
    ----------
    field_ids : iterable of int
        ZTF field IDs (unknown ones are ignored).
    prob : numpy.ndarray
        NESTED probability map.
    without : iterable of int
        Fields whose pixels do not count (a re-plan's executed pairs, P8).
    scope : CheckScope, optional
        Another telescope's fields and detectors (:mod:`.check_telescope`); default ZTF's.

    Returns
    -------
    float
    """
    nside = hp.npix2nside(prob.size)
    hit = _polygon_mask(field_ids, nside, scope) & ~_polygon_mask(without, nside, scope)
    return float(prob[hit].sum())


def polygon_mask(field_ids: Iterable[int], nside: int, scope: CheckScope | None = None) -> np.ndarray:
    """(npix,) True on the pixels whose centres lie inside one of the fields' detectors (a joint plan's union)."""
    return _polygon_mask(field_ids, nside, scope)


def _polygon_mask(field_ids: Iterable[int], nside: int, scope: CheckScope | None = None) -> np.ndarray:
    """(npix,) True on the pixels whose centres lie inside one of the fields' CCDs."""
    grid = field_positions() if scope is None else scope.positions
    offsets = None if scope is None else scope.offsets
    hit = np.zeros(hp.nside2npix(nside), bool)
    for fid in {int(f) for f in field_ids} & grid.keys():
        hit[_covered_pixels(*grid[fid], nside, offsets)] = True
    return hit


# --------------------------------------------------------------------------- telescope

def mount_reachable(ha_deg: np.ndarray, dec_deg: np.ndarray, ha_max_h: float) -> np.ndarray:
    """Can the P48 point there?  ZTF's queue rules as coded in ztf_sim.

    From ``ztf_sim/QueueManager.py`` (commit c5ab409, lines 1235-1253):
    |HA| below 5.95 h ("Reed limits"); HA < -17.6 deg with Dec < -22 deg is
    rejected (interference with the FFI); west of HA -17.6 deg, Dec < -45 deg
    is rejected (service platform); |HA| > 3 deg with Dec < -46 deg is
    rejected (shutter "ears"); Dec > 87.5 deg is rejected.

    Parameters
    ----------
    ha_deg, dec_deg : numpy.ndarray
        Hour angle (deg, in [-180, 180)) and declination (deg); broadcast.
    ha_max_h : float
        Largest |hour angle| (h).

    Returns
    -------
    numpy.ndarray of bool
    """
    ha = np.asarray(ha_deg, float)
    dec = np.asarray(dec_deg, float)
    rejected = (np.abs(ha) / 15.0 > ha_max_h) | (dec > 87.5)
    rejected |= (ha < -17.6) & (dec < -22.0)
    rejected |= (ha > -17.6) & (dec < -45.0)
    rejected |= (np.abs(ha) > 3.0) & (dec < -46.0)
    return ~rejected


def slew_seconds(ra1_deg: np.ndarray, dec1_deg: np.ndarray, ra2_deg: np.ndarray, dec2_deg: np.ndarray,
                 model: SlewModel) -> np.ndarray:
    """P48 slew time (s), settle included, from one field centre to the next.

    Each equatorial axis ramps up at its acceleration ``a`` to its top speed
    ``v``, cruises and ramps down again at the same rate; the two ramps take
    ``2 v / a`` seconds and cover ``v^2 / a`` degrees.  A shorter move never reaches
    ``v`` and takes ``2 sqrt(d / a)``.  The HA travel is the wrapped RA
    difference.  Both axes move at once: the slew lasts as long as the slower
    one, plus the settle time when anything moved (ztf_sim's
    ``constants.slew_time``).

    Parameters
    ----------
    ra1_deg, dec1_deg, ra2_deg, dec2_deg : numpy.ndarray
        Field centres (deg).
    model : SlewModel
        Drive parameters.

    Returns
    -------
    numpy.ndarray
    """
    d_ha = np.abs((np.asarray(ra2_deg, float) - ra1_deg + 540.0) % 360.0 - 180.0)
    d_dec = np.abs(np.asarray(dec2_deg, float) - dec1_deg)
    t = np.maximum(_axis(d_ha, model.ha_accel_deg_s2, model.ha_vmax_deg_s),
                   _axis(d_dec, model.dec_accel_deg_s2, model.dec_vmax_deg_s))
    return np.where(t > 0, t + model.settle_s, 0.0)


def _axis(d: np.ndarray, a: float, v: float) -> np.ndarray:
    """One axis's ramp up, cruise and ramp down over ``d`` deg (s)."""
    ramp_s, ramp_deg = 2.0 * v / a, v * v / a
    return np.where(d > ramp_deg, ramp_s + (d - ramp_deg) / v, 2.0 * np.sqrt(d / a))


def altaz_slew_seconds(ra1_deg: np.ndarray, dec1_deg: np.ndarray, ra2_deg: np.ndarray, dec2_deg: np.ndarray,
                       t_s: np.ndarray, start: Time, where: tuple[float, float, float], model: SlewModel) -> np.ndarray:
    """(M1) An alt-azimuth mount's slew time (s), settle included, starting at ``t_s`` (s since ``start``).

    Written out again from the definition: the local sidereal time is
    astropy's apparent one at ``start`` plus the sidereal rate times ``t_s``;
    a position's unit vector in the (meridian, east, pole) frame is projected
    on the zenith, the north and the east point of the site; the azimuth
    axis (``model.ha_*``) turns the shorter way, the altitude axis
    (``model.dec_*``) by the altitude difference; the slower sets the time.
    """
    lst0 = start.sidereal_time("apparent", longitude=where[1] * u.deg).deg
    lst = np.radians(lst0 + 360.98564736629 / 86400.0 * np.asarray(t_s, float))
    lat = np.radians(where[0])
    zenith, north = (np.cos(lat), 0.0, np.sin(lat)), (-np.sin(lat), 0.0, np.cos(lat))
    to_date = erfa.pnm06a(start.tt.jd1, start.tt.jd2)  # precession-nutation to the true equator of the start

    def horizontal(ra: np.ndarray, dec: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a, d = np.radians(np.asarray(ra, float)), np.radians(np.asarray(dec, float))
        x, y, z = (to_date[i, 0] * np.cos(d) * np.cos(a) + to_date[i, 1] * np.cos(d) * np.sin(a)
                   + to_date[i, 2] * np.sin(d) for i in range(3))  # the place of date, as a unit vector
        h = lst - np.arctan2(y, x)  # hour angle of date
        d = np.arcsin(np.clip(z, -1.0, 1.0))
        v = (np.cos(d) * np.cos(h), -np.cos(d) * np.sin(h), np.sin(d))
        up = sum(a * b for a, b in zip(v, zenith))
        toward_north = sum(a * b for a, b in zip(v, north))
        return np.degrees(np.arcsin(np.clip(up, -1, 1))), np.degrees(np.arctan2(v[1], toward_north))

    alt1, az1 = horizontal(ra1_deg, dec1_deg)
    alt2, az2 = horizontal(ra2_deg, dec2_deg)
    d_az = np.abs((az2 - az1 + 540.0) % 360.0 - 180.0)
    t = np.maximum(_axis(d_az, model.ha_accel_deg_s2, model.ha_vmax_deg_s),
                   _axis(np.abs(alt2 - alt1), model.dec_accel_deg_s2, model.dec_vmax_deg_s))
    return np.where(t > 0, t + model.settle_s, 0.0)


@functools.lru_cache(maxsize=8)
def p48_site(where: tuple[float, float, float] = P48_SITE) -> EarthLocation:
    """The P48's location (or another site's: latitude deg, longitude deg, height m)."""
    lat, lon, height = where
    return EarthLocation.from_geodetic(lon=lon * u.deg, lat=lat * u.deg, height=height * u.m)


@dataclass(frozen=True)
class Conditions:
    """Observing conditions at given times: each array has the times' shape."""

    sun_alt: np.ndarray  # deg
    airmass: np.ndarray  # sec z, inf below the horizon
    ha: np.ndarray  # apparent hour angle, deg in [-180, 180)
    moon_sep: np.ndarray  # deg


def conditions(start: Time, t_rel: np.ndarray, ra_deg: np.ndarray, dec_deg: np.ndarray,
               where: tuple[float, float, float] = P48_SITE) -> Conditions:
    """Sun altitude, airmass, hour angle and Moon separation of fields at times.

    Parameters
    ----------
    start : astropy.time.Time
        Reference time.
    t_rel : numpy.ndarray
        (n,) times (s since ``start``).
    ra_deg, dec_deg : numpy.ndarray
        (n,) ICRS position looked at, at each time.
    where : tuple of float
        The site (latitude deg, longitude deg, height m); default the P48's.

    Returns
    -------
    Conditions
    """
    loc = p48_site(where)
    lo, hi = float(t_rel.min()), float(t_rel.max())
    n_grid = max(5, int(np.ceil((hi - lo) / GRID_STEP_S)) + 1)
    grid_s = np.linspace(lo, hi + 1.0, n_grid)  # +1 s: never a zero-length grid
    times = start + TimeDelta(grid_s, format="sec")
    frame = AltAz(obstime=times, location=loc)

    # cubic Lagrange interpolation on the four grid times around each time (numpy only)
    x = (t_rel - lo) / (grid_s[1] - grid_s[0])
    b = np.clip(np.floor(x).astype(np.int64) - 1, 0, n_grid - 4)
    s = x - b
    weights = [np.prod([(s - m) / (k - m) for m in range(4) if m != k], axis=0) for k in range(4)]

    def cubic(values: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """``values`` (..., grid) at t_rel; with ``rows``, row ``rows[i]`` of a (fields, grid) array at t_rel[i]."""
        at = (lambda k: values[..., b + k]) if rows is None else (lambda k: values[rows, b + k])
        return sum(w * at(k) for k, w in enumerate(weights))

    sun = get_body("sun", times, loc).transform_to(frame)
    sin_sun = cubic(np.sin(sun.alt.rad))
    moon = get_body("moon", times, loc).cartesian.xyz.value  # (3, grid) topocentric, GCRS axes
    moon_dir = cubic(moon / np.linalg.norm(moon, axis=0, keepdims=True)).T

    fields, which = np.unique(np.stack([ra_deg, dec_deg], axis=1), axis=0, return_inverse=True)
    which = which.ravel()
    coords = SkyCoord(ra=fields[:, 0] * u.deg, dec=fields[:, 1] * u.deg)[:, None]
    altaz = coords.transform_to(frame)  # (fields, grid)
    alt, az, lat = altaz.alt.rad, altaz.az.rad, np.radians(where[0])
    sin_alt_grid = np.sin(alt)
    # hour angle from the same alt-az (azimuth from North through East):
    # cos(dec) sin(HA) = -cos(alt) sin(az), cos(dec) cos(HA) = cos(lat) sin(alt) - sin(lat) cos(alt) cos(az)
    ha_grid = np.degrees(np.unwrap(np.arctan2(-np.cos(alt) * np.sin(az),
                                              np.cos(lat) * np.sin(alt) - np.sin(lat) * np.cos(alt) * np.cos(az)),
                                   axis=1))
    sin_alt = cubic(sin_alt_grid, which)
    ha = cubic(ha_grid, which)

    moon_dir /= np.linalg.norm(moon_dir, axis=1, keepdims=True)
    cos_moon = np.einsum("ij,ij->i", moon_dir, _unit(ra_deg, dec_deg))
    with np.errstate(divide="ignore"):
        airmass = np.where(sin_alt > 0, 1.0 / np.where(sin_alt > 0, sin_alt, 1.0), np.inf)
    return Conditions(
        sun_alt=np.degrees(np.arcsin(np.clip(sin_sun, -1, 1))),
        airmass=airmass,
        ha=(ha + 180.0) % 360.0 - 180.0,
        moon_sep=np.degrees(np.arccos(np.clip(cos_moon, -1, 1))),
    )
