"""Per-exposure 5-sigma depth (scheduler_core.source.depth): calibration and the sky's effect."""

from __future__ import annotations

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import AltAz, SkyCoord, get_body
from astropy.time import Time

from mushrooms.scheduler_core.source.depth import (
    ZTF_DEPTH,
    ZTF_MEDIAN_DEPTH_30S,
    SkyConditions,
    dark_zenith,
    limiting_magnitude,
    science_depth,
    seeing_fwhm,
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


def test_median_science_depth_over_a_year_of_ztf_like_pointings_matches_published_medians() -> None:
    """Masci et al. 2019 / Bellm et al. 2019: median 5 sigma in 30 s g 20.8, r 20.6, i 19.9 (science images, D1)."""
    rng = np.random.default_rng(2019)
    grid = load_ztf_fields()
    jd = Time("2019-01-01T00:00:00", scale="utc").jd + rng.random(500) * 365.25
    cond = sky_conditions(grid.ra[:, None], grid.dec[:, None], Time(jd, format="jd", scale="utc"))
    ok = (cond.sun_alt_deg < -12) & (cond.airmass <= 2.0) & (cond.moon_sep_deg >= 20)
    assert ok.sum() > 20_000
    sel = SkyConditions(*(np.asarray(getattr(cond, f))[ok] for f in
                          ("airmass", "moon_alt_deg", "moon_sep_deg", "moon_phase_deg", "sun_alt_deg")))
    # the seeing calibration: median FWHM 2.0" in r over the same pointings (Bellm et al. 2019)
    assert np.median(seeing_fwhm(np.full(ok.sum(), "r"), sel.airmass)) == pytest.approx(2.0, abs=0.02)
    for band, published in ZTF_MEDIAN_DEPTH_30S.items():
        m5 = science_depth(np.full(ok.sum(), band), 30.0, sel)
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
        assert float(science_depth(band, 300.0, bright)) < float(science_depth(band, 300.0, dark)) - 1.5, band
        # the difference image: the reference caps the dark side, so the gap is smaller but still over 1 mag
        assert float(limiting_magnitude(band, 300.0, bright)) < float(limiting_magnitude(band, 300.0, dark)) - 1.0, band
        # the Moon's sky and the airmass each cost depth on their own
        assert float(sky_brightness(band, bright)) < float(sky_brightness(band, dark)) - 1.5


def test_science_depth_follows_exposure_time_airmass_moon_and_twilight() -> None:
    base = dark_zenith()
    m30 = float(science_depth("r", 30.0, base))
    assert float(science_depth("r", 300.0, base)) == pytest.approx(m30 + 1.25)

    def cond(**kw: float) -> SkyConditions:
        d = dict(airmass=1.0, moon_alt_deg=-30.0, moon_sep_deg=90.0, moon_phase_deg=180.0, sun_alt_deg=-30.0)
        d.update(kw)
        return SkyConditions(**{k: np.asarray(v, float) for k, v in d.items()})

    x = np.array([1.0, 1.5, 2.0, 2.5])
    m = science_depth(np.full(4, "g"), 30.0, cond(airmass=x))
    assert np.all(np.diff(m) < 0)
    # Moon up: fuller and closer is brighter sky, shallower limit
    phase = science_depth(np.full(3, "r"), 30.0, cond(moon_alt_deg=45.0, moon_phase_deg=np.array([150.0, 90.0, 0.0])))
    sep = science_depth(np.full(3, "r"), 30.0, cond(moon_alt_deg=45.0, moon_phase_deg=0.0,
                                                       moon_sep_deg=np.array([120.0, 60.0, 25.0])))
    assert np.all(np.diff(phase) < 0) and np.all(np.diff(sep) < 0)
    assert float(science_depth("r", 30.0, cond(moon_alt_deg=-5.0, moon_phase_deg=0.0))) == pytest.approx(m30)
    # twilight: the Sun at -12 deg costs ~1.2 mag (sky 2.5 mag brighter), nothing below -18 deg
    tw = science_depth(np.full(3, "r"), 30.0, cond(sun_alt_deg=np.array([-20.0, -15.0, -12.0])))
    assert tw[0] == pytest.approx(m30) and tw[1] < tw[0] and tw[0] - tw[2] == pytest.approx(1.2, abs=0.1)
    with pytest.raises(ValueError, match="no band z"):
        science_depth("z", 30.0, base)


def test_difference_image_is_shallower_than_the_science_image_and_gains_less_with_exposure() -> None:
    """(D2): the reference's noise caps the gain of long exposures; the broader PSF of the two sets the aperture."""
    base = dark_zenith(())
    for band in "gri":
        sci = np.array([float(science_depth(band, t, base)) for t in (30.0, 300.0, 600.0)])
        diff = np.array([float(limiting_magnitude(band, t, base)) for t in (30.0, 300.0, 600.0)])
        assert np.all(diff < sci), band
        assert diff[1] - diff[0] < 1.25 - 0.05 and diff[2] - diff[1] < diff[1] - diff[0], band
        assert np.all(diff < ZTF_DEPTH.reference_depth[band]), band
    # at the zenith the science PSF is sharper than the reference's: the difference has the reference's seeing,
    # so the science image's own seeing stops mattering; at airmass 2.5 the science PSF is the broader one
    def at(x: float) -> SkyConditions:
        return SkyConditions(airmass=np.asarray(x), moon_alt_deg=np.asarray(-30.0), moon_sep_deg=np.asarray(90.0),
                             moon_phase_deg=np.asarray(180.0), sun_alt_deg=np.asarray(-30.0))
    zen_loss = float(science_depth("r", 30.0, at(1.0)) - limiting_magnitude("r", 30.0, at(1.0)))
    high_loss = float(science_depth("r", 30.0, at(2.5)) - limiting_magnitude("r", 30.0, at(2.5)))
    fwhm_ratio = ZTF_DEPTH.reference_fwhm_arcsec["r"] / float(seeing_fwhm("r", 1.0))
    assert zen_loss == pytest.approx(2.5 * np.log10(fwhm_ratio), abs=0.03)
    assert high_loss < 0.03


#: Published ZTF 5-sigma depths (docs/design/detection.md, section 2.1), as read in the sources.
GCN_25418_30S_TYPICAL = 20.5      # GCN Circ. 25418: "exposures of 30s and a typical depth of ~20.5 mag"
ZTF_SPEC_30S_MEDIAN_R = 20.4      # ZTF technical specification: 30 s, median single visit 20.4 (R, all lunar phases)
GWEMOPT_ZTF_30S_R = 20.4          # gwemopt's ZTF.config: magnitude 20.4 for exposuretime 30 (filt r)
GW190425_DEPTH_GR = 21.0          # Coughlin et al. 2019 ApJL 885 L19, abstract: "a depth of ≈ 21 m_AB in g- and r-bands"
O3_MEDIAN_DEPTH = 20.8            # Kasliwal et al. 2020 ApJ 905 145, abstract: "median depth of 20.8 mag"


def _median_depths(jd: np.ndarray, exposures: tuple[float, ...], bands: str = "gr") -> dict[tuple[str, float], float]:
    """Median (D2) over ZTF-like pointings at the times jd (Sun < -12 deg, airmass <= 2, Moon >= 20 deg away)."""
    grid = load_ztf_fields()
    cond = sky_conditions(grid.ra[:, None], grid.dec[:, None], Time(jd, format="jd", scale="utc"))
    ok = (cond.sun_alt_deg < -12) & (cond.airmass <= 2.0) & (cond.moon_sep_deg >= 20)
    sel = SkyConditions(*(np.asarray(getattr(cond, f))[ok] for f in
                          ("airmass", "moon_alt_deg", "moon_sep_deg", "moon_phase_deg", "sun_alt_deg")))
    return {(b, t): float(np.median(limiting_magnitude(np.full(ok.sum(), b), t, sel))) for b in bands for t in exposures}


def test_d2_against_published_difference_image_depths() -> None:
    """D2 predicts the 30 s difference-image figures within 0.15 mag and the campaigns' medians at 30-60 s.

    The last lines pin a disagreement, not an agreement: at 300 s (D2) is
    0.6-1.1 mag deeper than the GW campaigns' medians, whose exposure times
    are not in the text read (detection.md section 2.1: the GW190425 time
    budget allows at most 2-3 min per exposure).  A change of the model that
    moves either shows here.
    """
    rng = np.random.default_rng(2019)
    year = Time("2019-01-01T00:00:00", scale="utc").jd + rng.random(300) * 365.25
    med = _median_depths(year, (30.0, 60.0, 300.0))
    for published in (ZTF_SPEC_30S_MEDIAN_R, GWEMOPT_ZTF_30S_R):
        assert 0.0 <= med["r", 30.0] - published <= 0.15
    assert abs(0.5 * (med["g", 30.0] + med["r", 30.0]) - GCN_25418_30S_TYPICAL) <= 0.15
    # the two nights after GW190425 (2019-04-25 08:18 UTC): 04:00-11:12 UTC on 04-25 and 04-26
    nights = np.concatenate([Time(d, scale="utc").jd + np.linspace(0.0, 0.30, 40)
                             for d in ("2019-04-25T04:00:00", "2019-04-26T04:00:00")])
    gw = _median_depths(nights, (30.0, 120.0, 300.0))
    for band in "gr":
        # ≈ 21 lies between 30 s (the survey's frames) and 2 min (about the most the two nights allow per exposure)
        assert gw[band, 30.0] - 0.1 <= GW190425_DEPTH_GR <= gw[band, 120.0], band
        assert 0.6 <= gw[band, 300.0] - GW190425_DEPTH_GR <= 1.1, band
        assert abs(med[band, 60.0] - O3_MEDIAN_DEPTH) <= 0.35, band
        assert 0.6 <= med[band, 300.0] - O3_MEDIAN_DEPTH <= 1.2, band
