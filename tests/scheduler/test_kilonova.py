"""Kilonova source model (scheduler_core.source.kilonova): alive from the merger on."""

from __future__ import annotations

import math

import healpy as hp
import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core.source.depth import ZTF_DEPTH
from mushrooms.evaluation.efficiency import DEFAULT_MAGLIM_300S, Injections, detected
from mushrooms.scheduler_core.source.kilonova import Kilonova, load_kilonova
from mushrooms.scheduler_core.source.lightcurves import load_lightcurve, parse_lightcurve
from mushrooms.scheduler_core.plan.document import Observation, Plan, PlanMetrics
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.sky.visibility import site

NSIDE = 32
MERGER = Time("2020-01-01T04:00:00", scale="utc")  # 20:00 local time at Palomar


def test_every_paper_curve_is_finite_from_the_merger_on_and_rises_no_faster_than_the_fireball() -> None:
    t = np.array([0.5, 1, 2, 3, 4]) / 24.0
    for name in ("optimistic", "conservative", "nsbh"):
        kn = load_kilonova(name)
        table = kn.lightcurve
        for band in ("g", "r", "i"):
            m = kn.absolute_mag(band, t)
            assert np.all(np.isfinite(m)) and np.all(np.diff(m) < 0), (name, band)
            assert np.all(np.isinf(table.absolute_mag(band, t)))  # the table alone: dark
            # (K1): at most 5 log10(t_a / t) fainter than any anchor epoch <= 1 d
            col = table.column(band)
            for ta, ma in zip(table.t_days, col):
                if ta <= 1.0 and np.isfinite(ma):
                    assert np.all(m <= ma + 5 * np.log10(ta / t) + 1e-9)
            # never fainter than the table, and the table's later epochs are untouched
            late = np.array([1.5, 3.0, 10.0])
            np.testing.assert_allclose(kn.absolute_mag(band, late), table.absolute_mag(band, late))
        assert math.isinf(float(kn.absolute_mag("r", 0.0))) and math.isinf(float(kn.absolute_mag("r", -0.1)))
        assert math.isinf(float(kn.absolute_mag("r", 25.0)))


def test_early_rise_from_a_hand_table() -> None:
    lc = parse_lightcurve("# t[days] g\n0.2 -14.0\n0.4 -16.0\n2.0 -15.0\n", "hand")
    kn = Kilonova(lc)
    # before 0.2 d the brightest bound comes from the 0.4 d anchor: -16 + 5 log10(0.4 / t)
    assert float(kn.absolute_mag("g", 0.1)) == pytest.approx(-16 + 5 * math.log10(4))
    # the 0.2 d epoch violates (K1) from 0.4 d and is lifted to -16 + 5 log10 2
    assert float(kn.absolute_mag("g", 0.2)) == pytest.approx(-16 + 5 * math.log10(2))
    # beyond 1 d only the table counts
    assert float(kn.absolute_mag("g", 1.5)) == pytest.approx(float(lc.absolute_mag("g", 1.5)))


def zenith_field(t: Time) -> tuple[float, float]:
    loc = site()
    return float(t.sidereal_time("apparent", longitude=loc.lon).deg), float(loc.lat.deg)


def one_exposure_plan(t_after_merger_s: float, band: str, ra: float, dec: float) -> Plan:
    obs = (Observation(1, ra, dec, band, t_after_merger_s, 300.0, 0),)
    return Plan("p", MERGER, MERGER + TimeDelta(86400, format="sec"), obs,
                PlanMetrics(0.0, "test", "test", None, 0.0, 1, 1))


@pytest.mark.parametrize("band", ["g", "r"])
def test_a_source_observed_only_in_the_first_3_h_at_40_mpc_is_detected(band) -> None:
    t_obs = 2.5 * 3600.0  # one 300 s exposure, 2.5 h to 2.58 h after the merger
    ra, dec = zenith_field(MERGER + TimeDelta(t_obs, format="sec"))
    ipix = hp.ang2pix(NSIDE, ra, dec, nest=True, lonlat=True)
    fp = Footprints(NSIDE, np.array([1]), np.array([0, 1]), np.array([ipix]))
    plan = one_exposure_plan(t_obs, band, ra, dec)

    def inj(d_mpc: float) -> Injections:
        return Injections(np.array([ipix]), NSIDE, np.array([ra]), np.array([dec]), np.array([d_mpc]), "fixed")

    kn = load_kilonova("conservative")
    assert detected(plan, kn, fp, inj(40.0), MERGER, ZTF_DEPTH).tolist() == [True]
    # not "always detected": the same exposure misses it at 400 Mpc
    assert detected(plan, kn, fp, inj(400.0), MERGER, ZTF_DEPTH).tolist() == [False]
    # the first release's model counted nothing before 0.202 d
    lc = load_lightcurve("conservative")
    assert detected(plan, lc, fp, inj(40.0), MERGER, DEFAULT_MAGLIM_300S).tolist() == [False]
