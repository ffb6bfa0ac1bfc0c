"""The Sun, the Moon and the sidereal time over a horizon: astropy on a coarse grid, interpolated.

Computing the Sun and the Moon with astropy (``get_body``, ``erfa.epv00``)
at every step of a one-minute grid costs about half a second per night;
what the constraints read of them varies slowly and smoothly in time, so
astropy is evaluated only at *nodes* ``GRID_ANCHOR + k * EPHEMERIS_STEP_S``
and every other time is interpolated linearly between the two nodes around
it (E1-E3):

* (E1) the Sun's topocentric apparent direction (true equator and equinox
  of date; it moves about 1 deg a day) and the Moon's topocentric one (GCRS
  axes, those of the fields' ICRS places; about 13 deg a day plus a daily
  parallax of about 1 deg), as unit vectors renormalised after
  interpolation;
* (E2) the local apparent sidereal time, unwrapped (it runs at a constant
  rate up to nutation);
* (E3) the Sun's and the Moon's altitudes in closed form from their
  interpolated hour angles and apparent declinations, as the fields'
  altitudes are computed (:func:`~.constraints.observing_geometry`); the
  Moon's phase angle (which moves 12 deg a day) linearly.

Nodes are whole steps from a fixed epoch, so a time's value does not depend
on which other times are asked with it (the daemon's per-night cache gives
the same windows as one alert's computation).  The interpolation error is
pinned by a test against astropy at every minute of a night (well under
0.01 deg for the Sun's altitude and the Moon's direction).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

import erfa
import numpy as np
from astropy.coordinates import EarthLocation, get_body
from astropy.time import Time, TimeDelta

__all__ = ["Ephemeris", "ephemeris", "EPHEMERIS_STEP_S", "GRID_ANCHOR"]

#: Spacing (s) of the nodes at which astropy computes the Sun, the Moon and the sidereal time.
EPHEMERIS_STEP_S = 600.0

#: Local mean noon at Palomar (lon -116.86 deg) on 2000-01-01: nodes are this plus whole steps; the
#: observability grid's times (:mod:`.visibility`) and nights are anchored on it too.
GRID_ANCHOR = Time("2000-01-01T19:47:26.4", scale="utc")


@dataclass(frozen=True)
class Ephemeris:
    """The Sun, the Moon and the local apparent sidereal time at m times.

    Attributes
    ----------
    sun_alt_deg : numpy.ndarray
        (m,) geometric altitude of the Sun (deg, no refraction).
    moon_ra_deg, moon_dec_deg : numpy.ndarray
        (m,) topocentric place of the Moon (deg, GCRS axes: comparable with ICRS field centres).
    lst_deg : numpy.ndarray
        (m,) local apparent sidereal time (deg, in [0, 360)).
    moon_alt_deg : numpy.ndarray
        (m,) geometric altitude of the Moon (deg, no refraction).
    moon_phase_deg : numpy.ndarray
        (m,) the Moon's phase angle (deg): 0 full, 180 new.
    """

    sun_alt_deg: np.ndarray
    moon_ra_deg: np.ndarray
    moon_dec_deg: np.ndarray
    lst_deg: np.ndarray
    moon_alt_deg: np.ndarray
    moon_phase_deg: np.ndarray


def _unit(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], axis=-1)


#: Nodes per cached chunk (6 h at the default step): alerts of one night, the windows and the executor's grid
#: of one plan reuse the chunks they share.
CHUNK_NODES = 36
#: Most chunks kept (about two weeks at the default step).
MAX_CHUNKS = 64

#: (chunk, step, lon, lat, height) -> node columns (see :func:`_astropy_at`) at the chunk's nodes, oldest first.
_chunks: "OrderedDict[tuple, tuple[np.ndarray, ...]]" = OrderedDict()
_lock = threading.Lock()


def _astropy_at(k: np.ndarray, step_s: float, location: EarthLocation) -> tuple[np.ndarray, ...]:
    """Astropy at nodes ``k``: one call per body.

    Returns (Sun unit vectors (TETE), Moon unit vectors (GCRS axes), Moon unit
    vectors (TETE), LST (rad), Moon phase angle (deg)).
    """
    times = GRID_ANCHOR + TimeDelta(k * step_s, format="sec")
    sun = get_body("sun", times, location)  # topocentric, GCRS axes: those of the fields' ICRS places
    moon = get_body("moon", times, location)
    sun_u, moon_u = _unit(sun.ra.deg, sun.dec.deg), _unit(moon.ra.deg, moon.dec.deg)
    to_date = erfa.pnm06a(times.tt.jd1, times.tt.jd2)  # GCRS -> true equator and equinox of date (TETE axes)
    lst = times.sidereal_time("apparent", longitude=location.lon).rad
    cos_elong = np.clip(np.sum(sun_u * moon_u, axis=1), -1.0, 1.0)
    d_sun, d_moon = sun.distance.to_value("km"), moon.distance.to_value("km")
    phase = np.degrees(np.arctan2(d_sun * np.sqrt(1.0 - cos_elong ** 2), d_moon - d_sun * cos_elong))
    return (np.einsum("nij,nj->ni", to_date, sun_u), moon_u, np.einsum("nij,nj->ni", to_date, moon_u),
            np.asarray(lst, float), np.asarray(phase, float))


def _nodes(k: np.ndarray, step_s: float, location: EarthLocation) -> tuple[np.ndarray, ...]:
    """The columns of :func:`_astropy_at` at nodes ``k`` (any shape of ints), from the cached chunks.

    Only the chunks holding ``k`` are read; those missing are computed
    together, in one astropy call per body.  Times too sparse for the cache
    (more chunks than it keeps, e.g. a year of random nights) get astropy
    at their own nodes only, uncached: a node's values are the same either way.
    """
    geo = location.to_geodetic()
    site_key = (float(step_s), float(geo.lon.deg), float(geo.lat.deg), float(geo.height.to_value("m")))
    wanted = np.unique(k // CHUNK_NODES)
    if wanted.size > MAX_CHUNKS:
        distinct, where = np.unique(k, return_inverse=True)
        return tuple(col[where] for col in _astropy_at(distinct, step_s, location))
    with _lock:
        have = {int(c): _chunks.get((int(c), *site_key)) for c in wanted}
    missing = [c for c, v in have.items() if v is None]
    if missing:
        nodes = np.concatenate([np.arange(c * CHUNK_NODES, (c + 1) * CHUNK_NODES) for c in missing])
        columns = _astropy_at(nodes, step_s, location)
        for i, c in enumerate(missing):
            have[c] = tuple(col[i * CHUNK_NODES:(i + 1) * CHUNK_NODES] for col in columns)
            for a in have[c]:
                a.setflags(write=False)
    with _lock:
        for c, v in have.items():
            _chunks[(c, *site_key)] = v
            _chunks.move_to_end((c, *site_key))
        while len(_chunks) > MAX_CHUNKS:
            _chunks.popitem(last=False)
    row = np.searchsorted(wanted, k // CHUNK_NODES) * CHUNK_NODES + k % CHUNK_NODES
    return tuple(np.concatenate([have[int(c)][i] for c in wanted])[row] for i in range(5))


def _altitude_deg(v: np.ndarray, lst_rad: np.ndarray, lat_rad: float) -> np.ndarray:
    """Geometric altitude (deg) of apparent (TETE) unit vectors ``v`` at sidereal time ``lst_rad`` (E3)."""
    ra, dec = np.arctan2(v[:, 1], v[:, 0]), np.arcsin(np.clip(v[:, 2], -1, 1))
    sin_alt = np.sin(lat_rad) * np.sin(dec) + np.cos(lat_rad) * np.cos(dec) * np.cos(lst_rad - ra)
    return np.degrees(np.arcsin(np.clip(sin_alt, -1, 1)))


def ephemeris(times: Time, location: EarthLocation, step_s: float = EPHEMERIS_STEP_S) -> Ephemeris:
    """The Sun's altitude, the Moon's place and phase and the sidereal time at ``times`` (E1-E3).

    Parameters
    ----------
    times : astropy.time.Time
        Times (UTC), any shape and order; sparse times (a year of random
        nights) cost only the chunks of nodes around them.
    location : astropy.coordinates.EarthLocation
        The observer.
    step_s : float
        Node spacing (s); smaller is closer to astropy and slower.

    Returns
    -------
    Ephemeris
        Arrays of the shape of ``times``.
    """
    t = np.atleast_1d((times - GRID_ANCHOR).to_value("s")).astype(float).ravel()
    x = t / step_s  # node coordinate: the weights do not depend on the other times asked
    whole = np.floor(x)
    j = whole.astype(np.int64)
    w = (x - whole)[:, None]
    both = _nodes(np.concatenate([j, j + 1]), step_s, location)
    before, after = [col[:j.size] for col in both], [col[j.size:] for col in both]

    def between(i: int) -> np.ndarray:  # (E1) linear, renormalised
        u = (1.0 - w) * before[i] + w * after[i]
        return u / np.linalg.norm(u, axis=1, keepdims=True)

    step = (after[3] - before[3]) % (2 * np.pi)  # the sidereal time runs forwards by ~2.5 deg a step
    lst = before[3] + w[:, 0] * step  # (E2)
    phase = (1.0 - w[:, 0]) * before[4] + w[:, 0] * after[4]
    s, m, m_app = between(0), between(1), between(2)
    lat = np.radians(float(location.to_geodetic().lat.deg))
    shape = np.shape(times)
    return Ephemeris(
        sun_alt_deg=_altitude_deg(s, lst, lat).reshape(shape),
        moon_ra_deg=(np.degrees(np.arctan2(m[:, 1], m[:, 0])) % 360.0).reshape(shape),
        moon_dec_deg=np.degrees(np.arcsin(np.clip(m[:, 2], -1, 1))).reshape(shape),
        lst_deg=(np.degrees(lst) % 360.0).reshape(shape),
        moon_alt_deg=_altitude_deg(m_app, lst, lat).reshape(shape),
        moon_phase_deg=phase.reshape(shape),
    )
