"""The loop benchmark's executor: a real greedy plan of a real sky map run through the telescope model (Q1-Q14)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from astropy.time import TimeDelta

from mushrooms.evaluation.queue_sim import Closure, achieved_coverage, execute_plan, random_closure
from mushrooms.scheduler_core import PlanningConfig, greedy_schedule, prepare_problem, read_skymap
from mushrooms.scheduler_core.executed import ExecutedExposure, done_pairs, is_done
from mushrooms.scheduler_core.planner import build_plan
from mushrooms.scheduler_core.telescope import TelescopeTiming

MAP = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


@pytest.fixture(scope="module")
def setup():
    cfg = PlanningConfig(solver="greedy", nside=64)  # coarse: the executor, not the map, is under test
    skymap = read_skymap(MAP, nside=cfg.nside)
    problem = prepare_problem(skymap, cfg, skymap.event_time)
    plan = build_plan(problem, greedy_schedule(problem), skymap, "greedy")
    assert len(plan.observations) >= 20
    return cfg, skymap, problem, plan


def rel(plan, t):
    return float((t - plan.start).to_value("s"))


def at(plan, seconds):
    return plan.start + TimeDelta(seconds, format="sec")


def night(plan):
    obs = plan.observations
    return at(plan, obs[0].start), at(plan, obs[-1].end)


def check_feasible(executed, plan, closures=()):
    """No two exposures overlap, none starts after the horizon, none runs inside a closure; each pair once."""
    prev = None
    for e in executed:
        t0, t1 = rel(plan, e.start), rel(plan, e.start) + e.exposure_s
        if e.status == "processed":
            for c in closures:
                assert t1 <= rel(plan, c.start) + 1e-6 or t0 >= rel(plan, c.end) - 1e-6
        assert t0 <= rel(plan, plan.end) + 1e-6
        if prev is not None:
            assert t0 >= rel(plan, prev.start) + prev.exposure_s + TelescopeTiming().slew.readout_s - 1e-3
        prev = e
    keys = [(e.field_id, e.filter) for e in executed if e.status == "processed"]
    assert len(keys) == len(set(keys))


def test_clear_night_keeps_the_plans_pairs_at_the_cadence(setup):
    cfg, skymap, problem, plan = setup
    executed = execute_plan(plan)
    assert all(isinstance(e, ExecutedExposure) and is_done(e) for e in executed)
    check_feasible(executed, plan)
    cov = achieved_coverage(executed, skymap, problem.footprints, cadence_s=cfg.cadence_s)
    assert cov == pytest.approx(plan.metrics.coverage_as_executed, abs=1e-6)
    assert cov >= 0.9 * plan.metrics.coverage
    pairs = done_pairs(executed, tuple(cfg.filters), cadence_s=cfg.cadence_s)
    starts = {(e.field_id, e.filter): rel(plan, e.start) for e in executed}
    for f in pairs.both:
        assert abs(starts[f, "r"] - starts[f, "g"]) >= cfg.cadence_s
    # no exposure before its pass's planned start: the queue windows open then
    planned = {(o.field_id, o.filter): o.start for o in plan.observations}
    first_of_pass = {}
    for o in plan.observations:
        first_of_pass.setdefault((o.block, o.filter), o.start)
    for e in executed:
        o = next(p for p in plan.observations if (p.field_id, p.filter) == (e.field_id, e.filter))
        assert rel(plan, e.start) >= first_of_pass[o.block, o.filter] - 1e-3
        assert (e.field_id, e.filter) in planned


def test_the_single_list_queue_squeezes_pairs_below_the_cadence(setup):
    cfg, skymap, problem, plan = setup
    single = execute_plan(plan, export="single")
    check_feasible(single, plan)
    any_sep = achieved_coverage(single, skymap, problem.footprints)
    at_cadence = achieved_coverage(single, skymap, problem.footprints, cadence_s=cfg.cadence_s)
    assert any_sep == pytest.approx(plan.metrics.coverage, abs=1e-5)  # everything observed ...
    assert at_cadence < plan.metrics.coverage_as_executed - 0.01  # ... but pairs come back too soon


def test_closure_through_the_night_costs_coverage_and_nothing_runs_in_it(setup):
    cfg, skymap, problem, plan = setup
    mid = at(plan, (plan.observations[0].start + plan.observations[-1].end) / 2)
    closure = Closure(mid, plan.end)
    executed = execute_plan(plan, closures=[closure])
    check_feasible(executed, plan, [closure])
    done = [e for e in executed if e.status == "processed"]
    assert 0 < len(done) < len(plan.observations)
    assert all(e.end <= mid for e in done)
    cov = achieved_coverage(executed, skymap, problem.footprints)
    assert 0 < cov < plan.metrics.coverage
    assert achieved_coverage(executed, skymap, problem.footprints, require="any") >= cov


def test_an_exposure_cut_by_the_closure_is_aborted_and_retaken(setup):
    cfg, skymap, problem, plan = setup
    clear = execute_plan(plan)
    victim = clear[3]
    closure = Closure(victim.start + TimeDelta(60, format="sec"), victim.start + TimeDelta(600, format="sec"))
    executed = execute_plan(plan, closures=[closure])
    aborted = [e for e in executed if e.status == "aborted"]
    assert len(aborted) == 1
    (a,) = aborted
    assert (a.field_id, a.filter) == (victim.field_id, victim.filter)
    assert a.processed_fraction == 0.0 and a.exposure_s == pytest.approx(60.0, abs=1e-3)
    again = [e for e in executed if (e.field_id, e.filter) == (a.field_id, a.filter) and e.status == "processed"]
    assert len(again) == 1 and again[0].start >= closure.end
    check_feasible(executed, plan, [closure])


def test_random_closure_is_seeded_and_inside_the_night(setup):
    _, _, _, plan = setup
    first, last = night(plan)
    closures = [random_closure(first, last, seed) for seed in range(20)]
    assert random_closure(first, last, 7) == random_closure(first, last, 7)
    assert len({round(c.start.unix) for c in closures}) == 20
    for c in closures:
        assert first <= c.start < c.end <= last
        assert 3600.0 - 1e-3 <= c.duration_s <= 3 * 3600.0 + 1e-3
    short = random_closure(first, first + TimeDelta(1800, format="sec"), np.random.default_rng(1))
    assert short.duration_s == pytest.approx(1800.0)  # cut to the night


@pytest.mark.parametrize("seed", [0, 1])
def test_seeded_weather_runs_are_feasible_and_repeatable(setup, seed):
    cfg, skymap, problem, plan = setup
    first, last = night(plan)
    closure = random_closure(first, last, seed)
    a = execute_plan(plan, closures=[closure])
    b = execute_plan(plan, closures=[closure])
    assert a == b
    check_feasible(a, plan, [closure])
    assert achieved_coverage(a, skymap, problem.footprints) <= plan.metrics.coverage + 1e-6


def test_a_late_start_takes_nothing_before_it_and_nothing_twice(setup):
    cfg, skymap, problem, plan = setup
    start = at(plan, plan.observations[len(plan.observations) // 2].start)
    executed = execute_plan(plan, start=start)
    assert executed and all(e.start >= start for e in executed)
    check_feasible(executed, plan)


def test_the_queues_expire_with_the_horizon(setup):
    cfg, skymap, problem, plan = setup
    cut = plan.with_(end=at(plan, plan.observations[10].start))
    executed = execute_plan(cut)
    assert executed and all(rel(cut, e.start) <= rel(cut, cut.end) + 1e-6 for e in executed)
    assert len(executed) < len(plan.observations)


def test_achieved_coverage_rules(setup):
    cfg, skymap, problem, plan = setup
    executed = execute_plan(plan)
    halves = [e for e in executed if e.filter == "g"]
    assert achieved_coverage(halves, skymap, problem.footprints) == 0.0
    assert achieved_coverage(halves, skymap, problem.footprints, require="any") == pytest.approx(
        plan.metrics.coverage, abs=1e-5)
    assert achieved_coverage([], skymap, problem.footprints) == 0.0
    with pytest.raises(ValueError):
        achieved_coverage(executed, skymap, problem.footprints, require="most")


def test_bad_arguments(setup):
    cfg, _, problem, plan = setup
    t = plan.start
    with pytest.raises(ValueError):
        Closure(t, t)
    with pytest.raises(ValueError):
        random_closure(t, t, 1)
    with pytest.raises(ValueError):
        random_closure(t, t + TimeDelta(7200, format="sec"), 1, min_h=2, max_h=1)
    with pytest.raises(ValueError):
        execute_plan(plan, export="fifo")


def test_the_bench_execution_cells_are_the_plans_queues_run_on_time_late_and_as_one_list(setup):
    from mushrooms.evaluation.queue_sim import execution_cells
    from mushrooms.scheduler_core.plan.exports import to_trigger_queue, to_trigger_queues
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.schedulers.as_executed import queue_coverage

    cfg, skymap, _, plan = setup
    footprints = field_footprints(load_ztf_fields(), cfg.nside)
    cells = execution_cells(plan, footprints, skymap.prob)
    assert cells["coverage_as_executed"] == pytest.approx(plan.metrics.coverage_as_executed, abs=1e-6)
    assert cells["n_queues"] == len(to_trigger_queues(plan)) > 1
    single = queue_coverage(plan, footprints, skymap.prob, queues=[to_trigger_queue(plan)])
    assert cells["coverage_single_queue"] == pytest.approx(single, abs=1e-6)
    for minutes in (15, 30, 60):
        late = queue_coverage(plan, footprints, skymap.prob, late_s=60.0 * minutes)
        assert cells[f"coverage_late_{minutes}"] == pytest.approx(late, abs=1e-6)
        assert cells[f"coverage_late_{minutes}"] <= plan.metrics.coverage + 1e-9
    empty = execution_cells(dataclasses.replace(plan, observations=()), footprints, skymap.prob)
    assert empty["n_queues"] == 0 and empty["coverage_as_executed"] == ""
