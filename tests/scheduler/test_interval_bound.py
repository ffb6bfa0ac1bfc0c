"""The interval bound (V1-V4): above every plan, never above U4, tighter where fields compete for time."""

from __future__ import annotations

import pytest
from astropy.time import Time

from conftest_milp import crowded_problem, random_problem, tiny_config
from tests_paths import MAP_FLAT_RING
from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.problem import PlanningProblem
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound, interval_violation


def _coverage(problem, result) -> float:
    return problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob)


@pytest.mark.parametrize("seed", range(8))
def test_interval_bound_is_above_every_plan_and_below_the_online_bound(seed):
    problem = random_problem(seed, n_fields=18, config=tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None,
                                                                    horizon_h=1.0, slot_positions=(1, 2, 3)))
    u4 = coverage_upper_bound(problem)
    v = interval_upper_bound(problem, time_limit_s=10.0)
    assert v.value <= u4.value + 1e-9
    for solver in ("greedy", "slots", "blocks"):
        result = run_scheduler(problem, solver)
        assert _coverage(problem, result) <= v.value + 1e-9, solver
        # every plan satisfies each interval row: the relaxation holds its field set
        assert interval_violation(problem, {o.field_id for o in result.observations}) <= 1e-6, solver


def _crowded_problem() -> PlanningProblem:
    """Three fields visible in [0, 600] s only (two fit), one in [1000, 1400] s (fits alone).

    Exposure 100 s, cadence 250 s, filter change 30 s, readout 8 s; the bound widens windows by the
    60 s time step.  Coverage: f1 = {0, 1} = .3, f2 = {2} = .22, f3 = {1, 3} = .22, f4 = {4} = .1; the best
    pair of fields 1-3 is {1, 2} = .52, so the optimum is .62 and all four fields cover .74.
    """
    return crowded_problem(600.0)


def test_fields_competing_for_the_same_minutes_tighten_the_bound():
    problem = _crowded_problem()
    u4 = coverage_upper_bound(problem)
    v = interval_upper_bound(problem, time_limit_s=10.0)
    assert u4.value == pytest.approx(0.74, abs=1e-9)  # every field: the night holds them all
    # [0, 660] s (windows widened by 60 s) holds 660 + 16 - 30 = 646 s < 3 * 216 s: two of fields 1-3
    assert v.value == pytest.approx(0.62, abs=1e-6)
    assert v.status == "interval"
    for solver in ("greedy", "slots"):
        assert _coverage(problem, run_scheduler(problem, solver)) <= v.value + 1e-9


def test_interval_bound_is_above_every_plan_on_a_test_map():
    cfg = PlanningConfig(time_limit_s=3.0, milp_backend="highs", min_gain=0.0, objective="coverage", threads=1)
    skymap = read_skymap(MAP_FLAT_RING, nside=cfg.nside)
    problem = prepare_problem(skymap, cfg, Time(skymap.event_time, scale="utc"))
    v = interval_upper_bound(problem, time_limit_s=5.0)
    assert 0 < v.value <= coverage_upper_bound(problem).value + 1e-9
    for solver in ("greedy", "slots", "hybrid"):
        plan = build_plan(problem, run_scheduler(problem, solver), skymap, solver)
        assert plan.metrics.coverage <= v.value + 1e-9, solver
