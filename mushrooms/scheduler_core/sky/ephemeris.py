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
* (E3) the Sun's altitude in closed form from its interpolated hour angle
  and declination, as the fields' altitudes are computed
  (:func:`~.constraints.observing_geometry`).

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

import numpy as np
from astropy.coordinates import TETE, EarthLocation, get_body
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
    """

    sun_alt_deg: np.ndarray
    moon_ra_deg: np.ndarray
    moon_dec_deg: np.ndarray
    lst_deg: np.ndarray


def _unit(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    return np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], axis=-1)


#: Nodes per cached chunk (6 h at the default step): alerts of one night, the windows and the executor's grid
#: of one plan reuse the chunks they share.
CHUNK_NODES = 36
#: Most chunks kept (about two weeks at the default step).
MAX_CHUNKS = 64

#: (chunk, step, lon, lat, height) -> (Sun, Moon unit vectors, LST (rad)) at the chunk's nodes, oldest first.
_chunks: "OrderedDict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray]]" = OrderedDict()
_lock = threading.Lock()


def _astropy_at(k: np.ndarray, step_s: float, location: EarthLocation
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Astropy at nodes ``k``: (Sun unit vectors (TETE), Moon unit vectors (GCRS axes), LST (rad)), one call each."""
    times = GRID_ANCHOR + TimeDelta(k * step_s, format="sec")
    sun = get_body("sun", times, location).transform_to(TETE(obstime=times, location=location))
    moon = get_body("moon", times, location)  # topocentric, GCRS axes: those of the fields' ICRS places
    lst = times.sidereal_time("apparent", longitude=location.lon).rad
    return _unit(sun.ra.deg, sun.dec.deg), _unit(moon.ra.deg, moon.dec.deg), np.asarray(lst, float)


def _nodes(k0: int, k1: int, step_s: float, location: EarthLocation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes ``k0..k1``: (Sun, Moon unit vectors, unwrapped LST (deg)), from the cached chunks.

    The chunks missing are computed together, in one astropy call per body.
    """
    geo = location.to_geodetic()
    site_key = (float(step_s), float(geo.lon.deg), float(geo.lat.deg), float(geo.height.to_value("m")))
    c0, c1 = k0 // CHUNK_NODES, k1 // CHUNK_NODES
    with _lock:
        have = {c: _chunks.get((c, *site_key)) for c in range(c0, c1 + 1)}
    missing = [c for c, v in have.items() if v is None]
    if missing:
        k = np.concatenate([np.arange(c * CHUNK_NODES, (c + 1) * CHUNK_NODES) for c in missing])
        sun, moon, lst = _astropy_at(k, step_s, location)
        for i, c in enumerate(missing):
            part = slice(i * CHUNK_NODES, (i + 1) * CHUNK_NODES)
            have[c] = (sun[part], moon[part], lst[part])
            for a in have[c]:
                a.setflags(write=False)
    with _lock:
        for c, v in have.items():
            _chunks[(c, *site_key)] = v
            _chunks.move_to_end((c, *site_key))
        while len(_chunks) > MAX_CHUNKS:
            _chunks.popitem(last=False)
    parts = [have[c] for c in range(c0, c1 + 1)]
    a, b = k0 - c0 * CHUNK_NODES, k1 - c0 * CHUNK_NODES + 1
    sun, moon, lst = (np.concatenate([p[i] for p in parts])[a:b] for i in range(3))
    return sun, moon, np.degrees(np.unwrap(lst))


def ephemeris(times: Time, location: EarthLocation, step_s: float = EPHEMERIS_STEP_S) -> Ephemeris:
    """The Sun's altitude, the Moon's place and the sidereal time at ``times`` (E1-E3).

    Parameters
    ----------
    times : astropy.time.Time
        (m,) times (UTC), any order.
    location : astropy.coordinates.EarthLocation
        The observer.
    step_s : float
        Node spacing (s); smaller is closer to astropy and slower.

    Returns
    -------
    Ephemeris
    """
    t = np.atleast_1d((times - GRID_ANCHOR).to_value("s")).astype(float).ravel()
    k0, k1 = int(np.floor(t.min() / step_s)), int(np.floor(t.max() / step_s)) + 1
    lat = float(location.to_geodetic().lat.deg)
    sun, moon, lst_nodes = _nodes(k0, k1, step_s, location)
    x = t / step_s  # node coordinate: the weights do not depend on the other times asked
    whole = np.floor(x)
    j = np.clip(whole.astype(np.int64) - k0, 0, k1 - k0 - 1)
    w = (x - whole)[:, None]

    def between(v: np.ndarray) -> np.ndarray:  # (E1) linear, renormalised
        u = (1.0 - w) * v[j] + w * v[j + 1]
        return u / np.linalg.norm(u, axis=1, keepdims=True)

    lst = (1.0 - w[:, 0]) * lst_nodes[j] + w[:, 0] * lst_nodes[j + 1]  # (E2)
    s, m = between(sun), between(moon)
    sun_ra, sun_dec = np.arctan2(s[:, 1], s[:, 0]), np.arcsin(np.clip(s[:, 2], -1, 1))
    ha = np.radians(lst) - sun_ra
    phi = np.radians(lat)
    sin_alt = np.sin(phi) * np.sin(sun_dec) + np.cos(phi) * np.cos(sun_dec) * np.cos(ha)  # (E3)
    shape = np.shape(times)
    return Ephemeris(
        sun_alt_deg=np.degrees(np.arcsin(np.clip(sin_alt, -1, 1))).reshape(shape),
        moon_ra_deg=(np.degrees(np.arctan2(m[:, 1], m[:, 0])) % 360.0).reshape(shape),
        moon_dec_deg=np.degrees(np.arcsin(np.clip(m[:, 2], -1, 1))).reshape(shape),
        lst_deg=(lst % 360.0).reshape(shape),
    )
