"""Per-exposure 5-sigma depth (scheduler_core.source.depth): calibration and the sky's effect."""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, SkyCoord, get_body
from astropy.time import Time

from mushrooms.scheduler_core.source.depth import (
    ZTF_MEDIAN_DEPTH_30S,
    SkyConditions,
    dark_zenith,
    limiting_magnitude,
    sky_brightness,
    sky_conditions,
)
from mushrooms.scheduler_core.sky.fields import load_ztf_fields
from mushrooms.scheduler_core.sky.visibility import site

FULL_MOON_NIGHT = Time("2020-01-11T08:00:00", scale="utc")  # full Moon 2020-01-10 19:21 UTC, high at Palomar
NEW_MOON_NIGHT = Time("2020-01-25T08:00:00", scale="utc")  # new Moon 2020-01-24 21:42 UTC


def pointing(alt_deg: float, az_deg: float, t: Time) -> tuple[float, float]:
    c = SkyCoord(AltAz(alt=alt_deg * u.deg, az=az_deg * u.deg, obstime=t, location=site())).icrs
    return float(c.ra.deg), float(c.dec.deg)


def test_median_depth_over_a_year_of_ztf_like_pointings_matches_published_medians() -> None:
    """Masci et al. 2019 / Bellm et al. 2019: median 5 sigma in 30 s g 20.8, r 20.6, i 19.9."""
    rng = np.random.default_rng(2019)
    grid = load_ztf_fields()
    jd = Time("2019-01-01T00:00:00", scale="utc").jd + rng.random(500) * 365.25
    cond = sky_conditions(grid.ra[:, None], grid.dec[:, None], Time(jd, format="jd", scale="utc"))
    ok = (cond.sun_alt_deg < -12) & (cond.airmass <= 2.0) & (cond.moon_sep_deg >= 20)
    assert ok.sum() > 20_000
    sel = SkyConditions(*(np.asarray(getattr(cond, f))[ok] for f in
                          ("airmass", "moon_alt_deg", "moon_sep_deg", "moon_phase_deg", "sun_alt_deg")))
    for band, published in ZTF_MEDIAN_DEPTH_30S.items():
        m5 = limiting_magnitude(np.full(ok.sum(), band), 30.0, sel)
        assert np.median(m5) == pytest.approx(published, abs=0.1), band
        # a real spread: bright time and high airmass cost up to ~1.5 mag
        lo, hi = np.percentile(m5, [5, 95])
        assert 0.8 < hi - lo < 2.5


def test_airmass_2p4_next_to_the_full_moon_is_shallower_than_the_zenith_on_a_dark_night() -> None:
    moon = get_body("moon", FULL_MOON_NIGHT, site()).transform_to(AltAz(obstime=FULL_MOON_NIGHT, location=site()))
    assert moon.alt.deg > 50
    alt_24 = float(np.degrees(np.arcsin(1 / 2.4)))
    bright = sky_conditions(*pointing(alt_24, moon.az.deg, FULL_MOON_NIGHT), FULL_MOON_NIGHT)
    dark = sky_conditions(*pointing(90.0, 0.0, NEW_MOON_NIGHT), NEW_MOON_NIGHT)
    assert float(bright.airmass) == pytest.approx(2.4, rel=0.01)
    assert float(bright.moon_phase_deg) < 15 and 20 < float(bright.moon_sep_deg) < 60
    assert float(dark.airmass) == pytest.approx(1.0, abs=0.01) and float(dark.moon_alt_deg) < 0
    for band in ("g", "r", "i"):
        m_bright = float(limiting_magnitude(band, 300.0, bright))
        m_dark = float(limiting_magnitude(band, 300.0, dark))
        assert m_bright < m_dark - 1.5, band
        # the Moon's sky and the airmass each cost depth on their own
        assert float(sky_brightness(band, bright)) < float(sky_brightness(band, dark)) - 1.5


def test_depth_follows_exposure_time_airmass_moon_and_twilight() -> None:
    base = dark_zenith()
    m30 = float(limiting_magnitude("r", 30.0, base))
    assert float(limiting_magnitude("r", 300.0, base)) == pytest.approx(m30 + 1.25)

    def cond(**kw: float) -> SkyConditions:
        d = dict(airmass=1.0, moon_alt_deg=-30.0, moon_sep_deg=90.0, moon_phase_deg=180.0, sun_alt_deg=-30.0)
        d.update(kw)
        return SkyConditions(**{k: np.asarray(v, float) for k, v in d.items()})

    x = np.array([1.0, 1.5, 2.0, 2.5])
    m = limiting_magnitude(np.full(4, "g"), 30.0, cond(airmass=x))
    assert np.all(np.diff(m) < 0)
    # Moon up: fuller and closer is brighter sky, shallower limit
    phase = limiting_magnitude(np.full(3, "r"), 30.0, cond(moon_alt_deg=45.0, moon_phase_deg=np.array([150.0, 90.0, 0.0])))
    sep = limiting_magnitude(np.full(3, "r"), 30.0, cond(moon_alt_deg=45.0, moon_phase_deg=0.0,
                                                       moon_sep_deg=np.array([120.0, 60.0, 25.0])))
    assert np.all(np.diff(phase) < 0) and np.all(np.diff(sep) < 0)
    assert float(limiting_magnitude("r", 30.0, cond(moon_alt_deg=-5.0, moon_phase_deg=0.0))) == pytest.approx(m30)
    # twilight: the Sun at -12 deg costs ~1.2 mag (sky 2.5 mag brighter), nothing below -18 deg
    tw = limiting_magnitude(np.full(3, "r"), 30.0, cond(sun_alt_deg=np.array([-20.0, -15.0, -12.0])))
    assert tw[0] == pytest.approx(m30) and tw[1] < tw[0] and tw[0] - tw[2] == pytest.approx(1.2, abs=0.1)
    with pytest.raises(ValueError, match="no band z"):
        limiting_magnitude("z", 30.0, base)


#: Published ZTF 5-sigma depths (docs/design/detection.md, section 2.1), as read in the sources.
GCN_25418_30S_TYPICAL = 20.5      # GCN Circ. 25418: "exposures of 30s and a typical depth of ~20.5 mag"
ZTF_SPEC_30S_MEDIAN_R = 20.4      # ZTF technical specification: 30 s, median single visit 20.4 (R, all lunar phases)
GW190425_DEPTH_GR = 21.0          # Coughlin et al. 2019 ApJL 885 L19, abstract: "a depth of ≈ 21 m_AB in g- and r-bands"
O3_MEDIAN_DEPTH = 20.8            # Kasliwal et al. 2020 ApJ 905 145, abstract: "median depth of 20.8 mag"


def _median_depths(jd: np.ndarray, exposures: tuple[float, ...], bands: str = "gr") -> dict[tuple[str, float], float]:
    """Median (D1) over ZTF-like pointings at the times jd (Sun < -12 deg, airmass <= 2, Moon >= 20 deg away)."""
    grid = load_ztf_fields()
    cond = sky_conditions(grid.ra[:, None], grid.dec[:, None], Time(jd, format="jd", scale="utc"))
    ok = (cond.sun_alt_deg < -12) & (cond.airmass <= 2.0) & (cond.moon_sep_deg >= 20)
    sel = SkyConditions(*(np.asarray(getattr(cond, f))[ok] for f in
                          ("airmass", "moon_alt_deg", "moon_sep_deg", "moon_phase_deg", "sun_alt_deg")))
    return {(b, t): float(np.median(limiting_magnitude(np.full(ok.sum(), b), t, sel))) for b in bands for t in exposures}


def test_d1_against_published_depths_beyond_30_s() -> None:
    """D1 agrees at 30 s (within 0.3 mag) and is ~1 mag deeper than the GW campaigns' medians at 300 s.

    The second half pins a disagreement, not an agreement (the campaigns'
    exposure times are not in the text read; detection.md section 2.1 lists
    what was searched and found, 2026-12-03): D1 at 300 s is 0.8-1.5 mag
    deeper than the published medians, and D1 at 30-60 s within 0.3 mag of
    them.  A change of D1's exposure scaling that moves either shows here.
    """
    rng = np.random.default_rng(2019)
    year = Time("2019-01-01T00:00:00", scale="utc").jd + rng.random(300) * 365.25
    med = _median_depths(year, (30.0, 60.0, 300.0))
    assert abs(med["r", 30.0] - ZTF_SPEC_30S_MEDIAN_R) <= 0.3
    assert abs(med["r", 30.0] - GCN_25418_30S_TYPICAL) <= 0.3 and abs(med["g", 30.0] - GCN_25418_30S_TYPICAL) <= 0.4
    # the two nights after GW190425 (2019-04-25 08:18 UTC): 04:00-11:12 UTC on 04-25 and 04-26
    nights = np.concatenate([Time(d, scale="utc").jd + np.linspace(0.0, 0.30, 40)
                             for d in ("2019-04-25T04:00:00", "2019-04-26T04:00:00")])
    gw = _median_depths(nights, (30.0, 300.0))
    for band in "gr":
        assert abs(gw[band, 30.0] - GW190425_DEPTH_GR) <= 0.3, band
        assert 0.8 <= gw[band, 300.0] - GW190425_DEPTH_GR <= 1.5, band
        assert abs(med[band, 60.0] - O3_MEDIAN_DEPTH) <= 0.45, band
        assert 0.8 <= med[band, 300.0] - O3_MEDIAN_DEPTH <= 1.5, band
