"""The interpolated Sun/Moon ephemeris (sky/ephemeris.py) against astropy at every minute of two nights."""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, SkyCoord, get_body
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core.sky.ephemeris import EPHEMERIS_STEP_S, ephemeris
from mushrooms.scheduler_core.sky.visibility import site

#: Largest error (deg) the interpolation may make: a fiftieth of the checker's Sun tolerance (0.05 deg).
MAX_ERROR_DEG = 1e-3


def _separation_deg(ra1, dec1, ra2, dec2):
    return SkyCoord(ra1 * u.deg, dec1 * u.deg).separation(SkyCoord(ra2 * u.deg, dec2 * u.deg)).deg


@pytest.mark.parametrize("start", ["2026-05-01T01:00:00", "2026-12-21T00:17:43"])  # full Moon near; a winter night
def test_sun_moon_and_sidereal_time_within_a_thousandth_of_a_degree_of_astropy(start):
    times = Time(start, scale="utc") + TimeDelta(np.arange(0, 14 * 3600, 60.0), format="sec")
    loc = site()
    got = ephemeris(times, loc)
    sun = get_body("sun", times, loc).transform_to(AltAz(obstime=times, location=loc)).alt.deg
    moon = get_body("moon", times, loc)
    lst = times.sidereal_time("apparent", longitude=loc.lon).deg
    assert np.max(np.abs(got.sun_alt_deg - sun)) < MAX_ERROR_DEG
    assert np.max(_separation_deg(got.moon_ra_deg, got.moon_dec_deg, moon.ra.deg, moon.dec.deg)) < MAX_ERROR_DEG
    assert np.max(np.abs((got.lst_deg - lst + 180.0) % 360.0 - 180.0)) < MAX_ERROR_DEG
    assert np.max(np.abs(got.moon_alt_deg - moon.transform_to(AltAz(obstime=times, location=loc)).alt.deg)) \
        < MAX_ERROR_DEG
    sun_gcrs = get_body("sun", times, loc)
    elong = sun_gcrs.separation(moon).rad
    d_sun, d_moon = sun_gcrs.distance.to_value("km"), moon.distance.to_value("km")
    phase = np.degrees(np.arctan2(d_sun * np.sin(elong), d_moon - d_sun * np.cos(elong)))
    assert np.max(np.abs(got.moon_phase_deg - phase)) < 0.05  # the phase angle moves 12 deg a day
    assert got.sun_alt_deg.min() < -18.0 < got.sun_alt_deg.max()  # dusk to dawn: the Sun crosses every limit


def test_a_time_has_one_value_whatever_is_asked_with_it():
    t0 = Time("2026-05-01T04:00:00", scale="utc")
    alone = ephemeris(t0 + TimeDelta([1234.5], format="sec"), site())
    among = ephemeris(t0 + TimeDelta(1234.5 + 997.0 * np.arange(-8, 30), format="sec"), site())
    k = 8
    assert alone.sun_alt_deg[0] == among.sun_alt_deg[k]
    assert alone.moon_ra_deg[0] == among.moon_ra_deg[k] and alone.lst_deg[0] == among.lst_deg[k]


def test_times_months_apart_get_the_values_of_a_dense_grid():
    """Sparse times (more node chunks than the cache keeps) give what they give among a night's dense grid."""
    base = Time("2026-01-01T00:00:00", scale="utc")
    night = np.arange(0.0, 3600.0, 97.0) + 120 * 86400.0 + 4 * 3600.0
    year = np.arange(100) * 3.7 * 86400.0
    dense = ephemeris(base + TimeDelta(night, format="sec"), site())
    sparse = ephemeris(base + TimeDelta(np.concatenate([night, year]), format="sec"), site())
    n = night.size
    for name in ("sun_alt_deg", "moon_alt_deg", "moon_ra_deg", "moon_phase_deg", "lst_deg"):
        assert np.allclose(getattr(sparse, name)[:n], getattr(dense, name), atol=1e-9, rtol=0), name
    assert np.ptp(sparse.moon_phase_deg[n:]) > 150  # a year: every phase


def test_times_on_the_nodes_are_astropys_and_shapes_follow_the_times():
    node = Time("2000-01-01T19:47:26.4", scale="utc") + TimeDelta(9600 * EPHEMERIS_STEP_S, format="sec")
    times = node + TimeDelta(np.array([[0.0, EPHEMERIS_STEP_S], [2 * EPHEMERIS_STEP_S, 3 * EPHEMERIS_STEP_S]]),
                             format="sec")
    got = ephemeris(times, site())
    assert got.sun_alt_deg.shape == (2, 2) and got.moon_dec_deg.shape == (2, 2)
    sun = get_body("sun", times.ravel(), site()).transform_to(AltAz(obstime=times.ravel(), location=site())).alt.deg
    assert np.max(np.abs(got.sun_alt_deg.ravel() - sun)) < 1e-4
