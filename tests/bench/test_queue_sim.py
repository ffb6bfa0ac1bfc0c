"""The loop benchmark's executor: a real greedy plan of a real sky map run through the list-queue model (Q1-Q6)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from astropy.time import TimeDelta

from mushrooms.evaluation.queue_sim import Closure, achieved_coverage, execute_plan, random_closure
from mushrooms.scheduler_core import PlanningConfig, greedy_schedule, prepare_problem, read_skymap
from mushrooms.scheduler_core.executed import ExecutedExposure, is_done
from mushrooms.scheduler_core.planner import build_plan
from mushrooms.scheduler_core.schedulers.slew import overhead_time

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


def check_feasible(executed, plan, problem, cfg, closures=()):
    """Every exposure inside a window, none overlapping, each after the overhead from the one before."""
    prev = None
    for e in executed:
        t0, t1 = rel(plan, e.start), rel(plan, e.start) + e.exposure_s
        if e.status == "processed":
            assert problem.windows.contains(e.field_id, t0 - 1e-3, t1 - 1e-3) or \
                problem.windows.contains(e.field_id, t0, t1)
            for c in closures:
                assert t1 <= rel(plan, c.start) + 1e-6 or t0 >= rel(plan, c.end) - 1e-6
        assert t1 <= rel(plan, plan.end) + 1e-6
        if prev is not None:
            assert t0 >= rel(plan, prev.start) + prev.exposure_s - 1e-3
        prev = e


def test_clear_night_executes_the_whole_plan(setup):
    cfg, skymap, problem, plan = setup
    executed = execute_plan(plan, problem.windows, cfg)
    assert all(isinstance(e, ExecutedExposure) and is_done(e) for e in executed)
    # all of it, in plan order but for what the queue passed over while its window was shut (Q1)
    assert sorted((e.field_id, e.filter) for e in executed) == sorted((o.field_id, o.filter) for o in plan.observations)
    assert [(e.field_id, e.filter) for e in executed[:5]] == [(o.field_id, o.filter) for o in plan.observations[:5]]
    check_feasible(executed, plan, problem, cfg)
    # the overheads are the slew model's
    by_key = {(o.field_id, o.filter): o for o in plan.observations}
    for a, b in zip(executed, executed[1:]):
        oa, ob = by_key[a.field_id, a.filter], by_key[b.field_id, b.filter]
        gap = rel(plan, b.start) - rel(plan, a.start) - a.exposure_s
        least = float(overhead_time(oa.ra, oa.dec, ob.ra, ob.dec, cfg.slew,
                                    cfg.filter_change_s if oa.filter != ob.filter else 0.0))
        assert gap >= least - 1e-3
    assert achieved_coverage(executed, skymap, problem.footprints) == pytest.approx(plan.metrics.coverage, abs=1e-5)


def test_closure_through_the_night_costs_coverage_and_nothing_runs_in_it(setup):
    cfg, skymap, problem, plan = setup
    first, last = night(plan)
    # the dome shuts for good half-way through the plan
    mid = at(plan, (plan.observations[0].start + plan.observations[-1].end) / 2)
    closure = Closure(mid, plan.end)
    executed = execute_plan(plan, problem.windows, cfg, closures=[closure])
    check_feasible(executed, plan, problem, cfg, [closure])
    done = [e for e in executed if e.status == "processed"]
    assert 0 < len(done) < len(plan.observations)
    assert all(e.end <= mid for e in done)
    cov = achieved_coverage(executed, skymap, problem.footprints)
    assert 0 < cov < plan.metrics.coverage
    assert achieved_coverage(executed, skymap, problem.footprints, require="any") >= cov


def test_an_exposure_cut_by_the_closure_is_aborted_and_retaken(setup):
    cfg, skymap, problem, plan = setup
    clear = execute_plan(plan, problem.windows, cfg)
    victim = clear[3]
    closure = Closure(victim.start + TimeDelta(60, format="sec"), victim.start + TimeDelta(600, format="sec"))
    executed = execute_plan(plan, problem.windows, cfg, closures=[closure])
    aborted = [e for e in executed if e.status == "aborted"]
    assert len(aborted) == 1
    (a,) = aborted
    assert (a.field_id, a.filter) == (victim.field_id, victim.filter)
    assert a.processed_fraction == 0.0 and a.exposure_s == pytest.approx(60.0, abs=1e-3)
    again = [e for e in executed if (e.field_id, e.filter) == (a.field_id, a.filter) and e.status == "processed"]
    assert len(again) == 1 and again[0].start >= closure.end
    check_feasible(executed, plan, problem, cfg, [closure])


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


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_seeded_weather_runs_are_feasible_and_repeatable(setup, seed):
    cfg, skymap, problem, plan = setup
    first, last = night(plan)
    closure = random_closure(first, last, seed)
    a = execute_plan(plan, problem.windows, cfg, closures=[closure])
    b = execute_plan(plan, problem.windows, cfg, closures=[closure])
    assert a == b
    check_feasible(a, plan, problem, cfg, [closure])
    assert achieved_coverage(a, skymap, problem.footprints) <= plan.metrics.coverage + 1e-6


def test_a_late_start_skips_what_has_set(setup):
    cfg, skymap, problem, plan = setup
    start = at(plan, plan.observations[len(plan.observations) // 2].start)
    executed = execute_plan(plan, problem.windows, cfg, start=start)
    assert executed and all(e.start >= start for e in executed)
    check_feasible(executed, plan, problem, cfg)
    # everything taken is in plan order among what remains possible, nothing twice
    keys = [(e.field_id, e.filter) for e in executed]
    assert len(keys) == len(set(keys))


def test_the_queue_expires_with_the_horizon(setup):
    cfg, skymap, problem, plan = setup
    cut = plan.with_(end=at(plan, plan.observations[10].start))
    executed = execute_plan(cut, problem.windows, cfg)
    assert executed and all(rel(cut, e.end) <= rel(cut, cut.end) + 1e-6 for e in executed)
    assert len(executed) < len(plan.observations)


def test_timed_queue_keeps_the_planned_times(setup):
    cfg, skymap, problem, plan = setup
    executed = execute_plan(plan, problem.windows, cfg, keep_planned_times=True)
    planned = {(o.field_id, o.filter): o.start for o in plan.observations}
    assert executed
    assert all(rel(plan, e.start) >= planned[e.field_id, e.filter] - 1e-3 for e in executed)
    check_feasible(executed, plan, problem, cfg)


def test_a_field_without_windows_is_never_observed(setup):
    cfg, skymap, problem, plan = setup
    w = problem.windows
    gone = plan.observations[0].field_id
    keep = w.field_ids != gone
    windows = type(w)(w.field_ids[keep], w.start[keep], w.end[keep])
    executed = execute_plan(plan, windows, cfg)
    assert gone not in {e.field_id for e in executed}
    assert len(executed) == len(plan.observations) - 2


def test_achieved_coverage_rules(setup):
    cfg, skymap, problem, plan = setup
    executed = execute_plan(plan, problem.windows, cfg)
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
        execute_plan(plan, problem.windows, cfg, idle_step_s=0)
