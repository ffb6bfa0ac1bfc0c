"""Large-neighbourhood re-solves (schedulers/portfolio/lns.py, H1-H5): exact on slices, never worse, through the checker."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time

from mushrooms.scheduler_core import PlanningConfig, check_plan, prepare_problem
from mushrooms.scheduler_core.plan.document import Observation
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.problem import PlanningProblem, ScheduleResult
from mushrooms.scheduler_core.schedulers.portfolio.lns import lns_improve, plan_rule_problems
from mushrooms.scheduler_core.telescope.slew import overhead_time
from mushrooms.scheduler_core.sky.footprints import Footprints
from mushrooms.scheduler_core.sky.windows import Windows


def small_problem(prob, members, windows, ra) -> PlanningProblem:
    cfg = PlanningConfig(nside=1, horizon_h=0.5, exposure_s=100.0, slew_estimate_s=10.0, filter_change_s=30.0,
                         cadence_s=250.0, milp_backend="highs", time_limit_s=5.0, mip_gap=0.0, min_gain=0.0,
                         objective="coverage", threads=1, deterministic=True)
    ids = np.arange(1, len(members) + 1)
    indptr = np.concatenate([[0], np.cumsum([len(m) for m in members])])
    fp = Footprints(cfg.nside, ids, indptr, np.concatenate([np.asarray(m, np.int64) for m in members]))
    w_ids = np.array([ids[f] for f, ws in enumerate(windows) for _ in ws])
    w_start = np.array([a for ws in windows for a, _ in ws], float)
    w_end = np.array([b for ws in windows for _, b in ws], float)
    return PlanningProblem(cfg, Time("2026-01-01T00:00:00", scale="utc"), np.asarray(prob, float), ids,
                           np.asarray(ra, float), np.zeros(len(members)), fp, Windows(w_ids, w_start, w_end))


def hand_problem() -> PlanningProblem:
    """Four fields on the equator at RA 0, 5, 10, 15 deg; exposure 100 s, cadence 250 s, filter change 30 s.

    Fields 1, 2, 3 are visible in [0, 600] s, where only two of them fit (six exposures and five overheads
    exceed 600 s); f1 = pixels {0, 1} (.3), f2 = {2} (.22), f3 = {1, 3} (.22): the best two are {1, 2}, .52.
    Field 4 = {4} (.1) is visible in [1000, 1400] s, where its pair fits alone.  Optimum .62 = {1, 2, 4}.
    """
    prob = [0.2, 0.1, 0.22, 0.12, 0.1, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7, 0.26 / 7]
    return small_problem(prob, [[0, 1], [2], [1, 3], [4]],
                         [[(0.0, 600.0)], [(0.0, 600.0)], [(0.0, 600.0)], [(1000.0, 1400.0)]],
                         [0.0, 5.0, 10.0, 15.0])


def timed(problem: PlanningProblem, sequence) -> tuple[Observation, ...]:
    """Exposures (field, filter) in this order, each as early as the window, overhead and cadence allow."""
    cfg = problem.config
    out: list[Observation] = []
    first: dict[int, float] = {}
    for fid, flt in sequence:
        r = int(np.flatnonzero(problem.field_ids == fid)[0])
        ra, dec = float(problem.ra[r]), float(problem.dec[r])
        t = problem.windows.for_field(fid)[0][0]
        if out:
            p = out[-1]
            t = max(t, p.start + p.exposure_s + float(overhead_time(
                p.ra, p.dec, ra, dec, cfg.slew, cfg.filter_change_s if p.filter != flt else 0.0)))
        if fid in first:
            t = max(t, first[fid] + cfg.cadence_s)
        first.setdefault(fid, t)
        out.append(Observation(fid, ra, dec, flt, t, cfg.exposure_s, 0))
    return tuple(out)


def coverage(problem: PlanningProblem, observations) -> float:
    return problem.footprints.coverage({o.field_id for o in observations}, problem.prob)


def as_result(observations) -> ScheduleResult:
    return ScheduleResult(tuple(observations), "seed", "given", None, 0.0)


def poor_seed(problem: PlanningProblem) -> ScheduleResult:
    """Fields 1 and 3 in the first window (.42), nothing in the second: rule-abiding and .2 below the optimum."""
    g, r = problem.config.filters
    return as_result(timed(problem, [(1, g), (3, g), (1, r), (3, r)]))


def test_the_poor_seed_keeps_the_rules_and_is_below_the_optimum():
    problem = hand_problem()
    seed = poor_seed(problem)
    assert plan_rule_problems(problem, seed.observations) == []
    assert coverage(problem, seed.observations) == pytest.approx(0.42)


def test_slices_reach_the_hand_checked_optimum_from_a_poor_seed():
    # 700 s slices every 350 s over [0, 1400]: one adds field 4, one swaps field 3 for field 2
    problem = hand_problem()
    out = lns_improve(problem, poor_seed(problem), time_limit_s=30.0, slice_s=700.0)
    assert out.status == "improved"
    assert coverage(problem, out.observations) == pytest.approx(0.62, abs=1e-9)
    assert {o.field_id for o in out.observations} == {1, 2, 4}
    assert plan_rule_problems(problem, out.observations) == []
    assert out.details["slices_improved"] >= 2


def test_one_slice_over_the_night_is_the_exact_model():
    problem = hand_problem()
    out = lns_improve(problem, as_result(()), time_limit_s=30.0, slice_s=10_000.0)
    assert coverage(problem, out.observations) == pytest.approx(0.62, abs=1e-9)


def test_a_slice_keeps_the_exposures_outside_it_where_they_are():
    # the slice [700, 1400] adds field 4; fields 1 and 3 outside it do not move
    problem = hand_problem()
    seed = poor_seed(problem)
    out = lns_improve(problem, seed, time_limit_s=30.0, slice_s=700.0, max_free=1)
    kept = {(o.field_id, o.filter): o.start for o in out.observations}
    moved = [o for o in seed.observations if kept.get((o.field_id, o.filter)) != o.start]
    assert 4 in {o.field_id for o in out.observations}
    # with one free field per slice, [0, 700] frees nothing new but fields 1, 3: it may swap them; the
    # exposures that stayed are exactly where the seed had them
    assert all(kept[(o.field_id, o.filter)] == o.start for o in seed.observations if o not in moved)
    assert plan_rule_problems(problem, out.observations) == []
    assert coverage(problem, out.observations) >= coverage(problem, seed.observations)


def test_a_slice_of_two_intervals_places_a_pair_hours_apart():
    # field 1 is visible in [0, 150] and [1300, 1400] s only: its pair spans the two (the cadence is a least
    # separation); field 2 in [500, 1000] s.  A 300 s interval holds no pair (cadence + exposure = 350 s), so
    # only the slices of two intervals add them
    problem = small_problem([0.5, 0.2] + [0.3 / 10] * 10, [[0], [1]], [[(0.0, 150.0), (1300.0, 1400.0)],
                                                                      [(500.0, 1000.0)]], [0.0, 5.0])
    out = lns_improve(problem, as_result(()), time_limit_s=30.0, slice_s=300.0)
    assert {o.field_id for o in out.observations} == {1, 2}
    assert coverage(problem, out.observations) == pytest.approx(0.7, abs=1e-9)
    assert plan_rule_problems(problem, out.observations) == []
    t1 = sorted(o.start for o in out.observations if o.field_id == 1)
    assert t1[0] + 100.0 <= 150.0 + 1e-9 and t1[1] >= 1300.0 - 1e-9


def test_an_optimal_seed_comes_back_unchanged():
    problem = hand_problem()
    best = lns_improve(problem, as_result(()), time_limit_s=30.0, slice_s=10_000.0)
    again = lns_improve(problem, best, time_limit_s=30.0, slice_s=700.0)
    assert again.status == "no_improvement"
    assert again.observations == tuple(sorted(best.observations, key=lambda o: o.start))


def test_should_stop_returns_the_seed():
    problem = hand_problem()
    seed = poor_seed(problem)
    out = lns_improve(problem, seed, should_stop=lambda: True, time_limit_s=30.0, slice_s=700.0)
    assert out.status == "interrupted"
    assert out.observations == seed.observations
    assert out.details["slices_tried"] == 0


def test_a_seed_of_another_shape_comes_back_unchanged():
    problem = hand_problem()
    g, _ = problem.config.filters
    lone = as_result(timed(problem, [(1, g)]))  # one filter only
    out = lns_improve(problem, lone, time_limit_s=5.0)
    assert out.status == "unsupported_seed" and out.observations == lone.observations


def test_on_a_real_map_the_lns_repairs_a_thinned_greedy_plan_and_passes_the_checker(skymap_220722v):
    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=8.0, milp_backend="highs", min_gain=0.0,
                         deterministic=True)
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    greedy = run_scheduler(problem, "greedy")
    fields = sorted({o.field_id for o in greedy.observations})
    drop = set(fields[::2])
    thinned = as_result(o for o in greedy.observations if o.field_id not in drop)
    out = lns_improve(problem, thinned, time_limit_s=8.0)
    assert coverage(problem, out.observations) > coverage(problem, thinned.observations)
    assert plan_rule_problems(problem, out.observations) == []
    result = dataclasses.replace(thinned, observations=out.observations, solver=out.solver, status=out.status)
    report = check_plan(build_plan(problem, result, skymap_220722v, "hybrid"), skymap_220722v, cfg)
    assert report.ok, report.problems[:3]


def test_the_hybrid_never_publishes_less_than_its_best_earlier_stage(skymap_220722v):
    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=6.0, milp_backend="highs", deterministic=True)
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    result = run_scheduler(problem, "hybrid")
    covs = {e.name: e.coverage for e in result.portfolio}
    assert "lns" in covs
    assert covs["lns"] >= max(covs[n] for n in ("greedy", "slots") if n in covs) - 1e-12
    report = check_plan(build_plan(problem, result, skymap_220722v, "hybrid"), skymap_220722v, cfg)
    assert report.ok, report.problems[:3]


BNS_14 = Path(__file__).resolve().parents[3] / "shared" / "data" / "skymaps" / "simulated" / "bns_o3" / "14.fits"
if not BNS_14.is_file():
    BNS_14 = Path("/work/shared/data/skymaps/simulated/bns_o3/14.fits")


@pytest.mark.slow
@pytest.mark.skipif(not BNS_14.is_file(), reason="shared sky maps not present")
def test_the_lns_never_keeps_a_plan_that_ztf_executes_worse_than_its_seed():
    # bns_o3/14 on its top 20 fields: a plan packed to the cadence up to the night's end covers more as planned,
    # but the executor's later pass starts push its last pairs out of the night
    from mushrooms.evaluation.reduced import reduced_problem
    from mushrooms.scheduler_core import read_skymap
    from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverage_as_executed

    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=10.0, milp_backend="highs", min_gain=0.0,
                         min_coverage=0.0, deterministic=True)
    sm = read_skymap(BNS_14, nside=cfg.nside)
    problem = reduced_problem(prepare_problem(sm, cfg, Time(sm.event_time, scale="utc")), 20)
    seed = run_scheduler(problem, "slots")
    out = lns_improve(problem, seed, time_limit_s=12.0, max_idle_s=12.0)
    assert out.details["slices_tried"] > 0
    _, executed_seed = keyed_coverage_as_executed(problem, seed)
    _, executed_out = keyed_coverage_as_executed(problem, out)
    assert executed_out >= executed_seed - 1e-9
    assert coverage(problem, out.observations) >= coverage(problem, seed.observations) - 1e-12
    assert plan_rule_problems(problem, out.observations) == []
