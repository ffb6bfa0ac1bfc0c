"""Detection efficiency: injections from the map, footprint x light curve x depth."""

from __future__ import annotations

import math

import healpy as hp
import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.evaluation.efficiency import (
    DEFAULT_MAGLIM_300S,
    detected,
    detection_efficiency,
    draw_injections,
    flat_limiting_magnitude,
)
from mushrooms.scheduler_core.source.lightcurves import load_lightcurve, parse_lightcurve
from mushrooms.scheduler_core.plan.document import Observation, Plan, PlanMetrics
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.sky.skymap import SkyMap

NSIDE = 32
NPIX = 12 * NSIDE**2
MERGER = Time("2020-01-01T00:00:00", scale="utc")
N = 20_000
INF_DEEP = {"g": math.inf, "r": math.inf}
FLAT = parse_lightcurve("# t[days] g r\n0.5 -16.0 -16.0\n1.5 -16.0 -16.0\n2.0 -10.0 -10.0\n3.0 -10.0 -10.0\n", "flat")


def make_skymap(prob: np.ndarray | None = None, mu: float | None = 100.0, sigma: float = 20.0,
                sha: str = "a" * 64) -> SkyMap:
    prob = np.full(NPIX, 1.0 / NPIX) if prob is None else prob / prob.sum()
    if mu is None:
        layers = (None, None, None)
    else:
        from ligo.skymap.distance import parameters_to_moments

        norm = parameters_to_moments(mu, sigma)[2]
        layers = (np.full(NPIX, mu), np.full(NPIX, sigma), np.full(NPIX, norm))
    return SkyMap(prob=prob, nside=NSIDE, event_time=MERGER, object_id="TEST", distmu=layers[0],
                  distsigma=layers[1], distnorm=layers[2], distmean=mu, sha256=sha, source="<test>")


def make_footprints(rows: dict[int, np.ndarray]) -> Footprints:
    ids = np.array(sorted(rows), dtype=np.int64)
    parts = [np.sort(np.asarray(rows[i], dtype=np.int64)) for i in ids]
    indptr = np.concatenate([[0], np.cumsum([p.size for p in parts])]).astype(np.int64)
    return Footprints(NSIDE, ids, indptr, np.concatenate(parts))


def make_plan(obs: list[tuple[int, str, float]], start: Time = MERGER) -> Plan:
    """obs: (field_id, filter, start in s since the plan start), 300 s each."""
    observations = tuple(Observation(f, 0.0, 0.0, flt, t, 300.0, 0) for f, flt, t in obs)
    metrics = PlanMetrics(0.0, "test", "test", None, 0.0, len({o[0] for o in obs}), len(obs))
    return Plan("p", start, start + TimeDelta(86400, format="sec"), observations, metrics)


ALL = make_footprints({1: np.arange(NPIX)})
DAY = 86400.0


def test_full_coverage_infinitely_deep_plan_detects_everything() -> None:
    sm = make_skymap()
    inj = draw_injections(sm, N)
    plan = make_plan([(1, "g", 1.0 * DAY)])
    eff = detection_efficiency(plan, sm, load_lightcurve("optimistic"), INF_DEEP, ALL, inj)
    assert eff == pytest.approx(1.0, abs=3 * math.sqrt(1.0 / N))
    assert eff == 1.0


def test_empty_plan_detects_nothing() -> None:
    sm = make_skymap()
    inj = draw_injections(sm, N)
    eff = detection_efficiency(make_plan([]), sm, load_lightcurve("optimistic"), INF_DEEP, ALL, inj)
    assert eff == 0.0


def test_half_the_sky_gives_half_within_monte_carlo_error() -> None:
    sm = make_skymap()
    inj = draw_injections(sm, N)
    half = make_footprints({7: np.arange(NPIX // 2)})
    eff = detection_efficiency(make_plan([(7, "r", DAY)]), sm, FLAT, INF_DEEP, half, inj)
    assert abs(eff - 0.5) < 4 * math.sqrt(0.25 / N)


def test_probability_weighting_of_positions() -> None:
    prob = np.zeros(NPIX)
    prob[:10] = 9.0  # 90 % in ten pixels
    prob[10:20] = 1.0
    sm = make_skymap(prob)
    inj = draw_injections(sm, N)
    assert set(np.unique(inj.ipix)) <= set(range(20))
    fp = make_footprints({3: np.arange(10)})
    eff = detection_efficiency(make_plan([(3, "g", DAY)]), sm, FLAT, INF_DEEP, fp, inj)
    assert abs(eff - 0.9) < 4 * math.sqrt(0.09 / N)


def test_positions_lie_inside_their_pixels_and_draws_are_reproducible() -> None:
    sm = make_skymap()
    a, b = draw_injections(sm, 5000), draw_injections(sm, 5000)
    np.testing.assert_array_equal(hp.ang2pix(NSIDE, a.ra, a.dec, nest=True, lonlat=True), a.ipix)
    np.testing.assert_array_equal(a.ipix, b.ipix)
    np.testing.assert_array_equal(a.distance_mpc, b.distance_mpc)
    c = draw_injections(make_skymap(sha="b" * 64), 5000)
    assert not np.array_equal(a.ipix, c.ipix)
    # inside the pixel, not at its centre
    centre = hp.pix2ang(NSIDE, a.ipix, nest=True, lonlat=True)
    assert np.mean(np.abs(a.ra - centre[0]) > 1e-6) > 0.9


def test_distance_samples_follow_the_map_ansatz() -> None:
    from ligo.skymap.distance import parameters_to_moments

    for mu, sigma in ((100.0, 20.0), (40.0, 60.0)):
        inj = draw_injections(make_skymap(mu=mu, sigma=sigma), N)
        mean, std, _ = parameters_to_moments(mu, sigma)
        assert np.all(inj.distance_mpc > 0)
        assert inj.distance_mpc.mean() == pytest.approx(mean, abs=5 * std / math.sqrt(N))
        assert inj.distance_mpc.std() == pytest.approx(std, rel=0.05)


def test_real_map_distance_moments(data_dir) -> None:
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    sm = read_skymap(data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    inj = draw_injections(sm, N)
    # the header's DISTMEAN is the posterior mean distance over the whole sky
    assert inj.distance_mpc.mean() == pytest.approx(sm.distmean, rel=0.05)


def test_map_without_distance_needs_a_fixed_distance() -> None:
    sm = make_skymap(mu=None)
    assert draw_injections(sm, 100) is None
    inj = draw_injections(sm, 100, fixed_distance_mpc=40.0)
    assert inj.distance_source == "fixed"
    np.testing.assert_array_equal(inj.distance_mpc, 40.0)


def test_detection_follows_the_light_curve_in_time() -> None:
    sm = make_skymap(mu=100.0, sigma=1.0)  # everything at ~100 Mpc: mu = 35.0 mag
    inj = draw_injections(sm, 5000)
    maglim = {"g": 20.0, "r": 20.0}  # needs M <= -15.0
    lc = FLAT  # -16 from 0.5 to 1.5 d, -10 from 2 d on, nothing before 0.5 d
    eff = {}
    for label, t_days in (("early", 0.3), ("bright", 1.0), ("faded", 2.5)):
        plan = make_plan([(1, "g", t_days * DAY)])
        eff[label] = detection_efficiency(plan, sm, lc, maglim, ALL, inj)
    assert eff["bright"] == 1.0
    assert eff["faded"] == 0.0
    assert eff["early"] == 0.0  # before the first tabulated time: not detectable
    # the same plan started later: the plan start offset counts too
    late = make_plan([(1, "g", 0.0)], start=MERGER + TimeDelta(2.5 * DAY, format="sec"))
    assert detection_efficiency(late, sm, lc, maglim, ALL, inj) == 0.0
    # a real kilonova fades: a plan a week after merger detects fewer than at 1 day
    opt = load_lightcurve("optimistic")
    far = draw_injections(make_skymap(mu=150.0, sigma=50.0), 5000)
    sm150 = make_skymap(mu=150.0, sigma=50.0)
    e1 = detection_efficiency(make_plan([(1, "r", 1.0 * DAY)]), sm150, opt, DEFAULT_MAGLIM_300S, ALL, far)
    e7 = detection_efficiency(make_plan([(1, "r", 7.0 * DAY)]), sm150, opt, DEFAULT_MAGLIM_300S, ALL, far)
    assert e1 > 0.5 and e7 < 0.1


def test_depth_and_distance_thresholds() -> None:
    sm = make_skymap(mu=100.0, sigma=1.0)
    inj = draw_injections(sm, 2000)
    plan = make_plan([(1, "r", DAY)])
    mu = inj.distance_modulus
    for lim in (19.5, 19.0, 18.9):  # absolute -16: detected when mu <= lim + 16
        hits = detected(plan, FLAT, ALL, inj, MERGER, {"r": lim, "g": lim})
        np.testing.assert_array_equal(hits, mu <= lim + 16.0)


def test_one_covering_exposure_suffices_and_uncovered_fields_do_not_count() -> None:
    sm = make_skymap()
    inj = draw_injections(sm, N)
    half_a = np.arange(NPIX // 2)
    half_b = np.arange(NPIX // 2, NPIX)
    fp = make_footprints({1: half_a, 2: half_b})
    both = make_plan([(1, "g", DAY), (2, "r", DAY + 400)])
    only_a_deep = detected(make_plan([(1, "g", DAY)]), FLAT, fp, inj, MERGER, INF_DEEP)
    assert detection_efficiency(both, sm, FLAT, INF_DEEP, fp, inj) == 1.0
    np.testing.assert_array_equal(only_a_deep, inj.ipix < NPIX // 2)
    # the filter's limit is used: g too shallow, r deep enough
    lims = {"g": 0.0, "r": math.inf}
    hits = detected(both, FLAT, fp, inj, MERGER, lims)
    np.testing.assert_array_equal(hits, inj.ipix >= NPIX // 2)


def test_flat_limiting_magnitude_scales_with_exposure_time() -> None:
    m = flat_limiting_magnitude(np.array(["r", "g", "r"]), np.array([300.0, 300.0, 30.0]))
    np.testing.assert_allclose(m, [21.7, 21.7, 21.7 - 1.25])
    with pytest.raises(ValueError, match="filter"):
        flat_limiting_magnitude(np.array(["z"]), np.array([300.0]))


def test_vectorised_detection_matches_a_plain_reference() -> None:
    rng = np.random.default_rng(3)
    fields = {f: rng.choice(NPIX, size=rng.integers(50, 4000), replace=False) for f in range(1, 6)}
    fp = make_footprints(fields)
    sm = make_skymap(mu=120.0, sigma=60.0)
    inj = draw_injections(sm, 400)
    obs = [(int(rng.integers(1, 6)), str(rng.choice(["g", "r"])), float(rng.uniform(0.0, 5.0) * DAY))
           for _ in range(25)]
    plan = make_plan(obs, start=MERGER + TimeDelta(0.1 * DAY, format="sec"))
    lc = load_lightcurve("conservative")
    lims = {"g": 21.0, "r": 21.5}
    fast = detected(plan, lc, fp, inj, MERGER, lims, chunk=4)
    slow = np.zeros(len(inj), dtype=bool)
    for i in range(len(inj)):
        for o in plan.observations:
            t = 0.1 + (o.start + o.exposure_s / 2) / DAY
            m = float(lc.absolute_mag(o.filter, t)) + 5 * math.log10(inj.distance_mpc[i] * 1e5)
            if inj.ipix[i] in set(fields[o.field_id].tolist()) and m <= lims[o.filter]:
                slow[i] = True
                break
    assert slow.any() and not slow.all()
    np.testing.assert_array_equal(fast, slow)
