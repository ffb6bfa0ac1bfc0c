"""The interval bound on the outer refined windows (V7, [scheduler] bound_refine_ends): valid, tighter, opt in."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from astropy.time import Time

from tests_paths import MAP_220722V
from mushrooms.evaluation.exact import solve_exact
from mushrooms.evaluation.reduced import reduced_problem
from mushrooms.evaluation.true_windows import refined_problem
from mushrooms.scheduler_core import PlanningConfig, check_plan, prepare_problem, read_skymap
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound

BNS_14 = Path(__file__).resolve().parents[3] / "shared" / "data" / "skymaps" / "simulated" / "bns_o3" / "14.fits"
if not BNS_14.is_file():
    BNS_14 = Path("/work/shared/data/skymaps/simulated/bns_o3/14.fits")


def _refined(problem, on: bool = True):
    return dataclasses.replace(problem, config=dataclasses.replace(problem.config, bound_refine_ends=on))


def _problem(path: Path, **overrides):
    values = dict(objective="coverage", threads=1, time_limit_s=3.0, milp_backend="highs", min_gain=0.0,
                  min_coverage=0.0)
    values.update(overrides)
    cfg = PlanningConfig(**values)
    skymap = read_skymap(path, nside=cfg.nside)
    return skymap, prepare_problem(skymap, cfg, Time(skymap.event_time, scale="utc"))


def test_the_key_is_recorded_only_when_true():
    assert "bound_refine_ends" not in PlanningConfig().record()
    assert PlanningConfig(bound_refine_ends=True).record()["bound_refine_ends"] is True


@pytest.fixture(scope="module")
def map_220722v():
    return _problem(MAP_220722V, bound_refine_ends=True)


def test_every_scheduler_plan_is_below_the_refined_bound(map_220722v):
    skymap, problem = map_220722v
    bound = certified_upper_bound(problem)
    assert bound.value <= coverage_upper_bound(problem).value + 1e-9
    for name in ("greedy", "slots", "hybrid"):
        result = run_scheduler(problem, name)
        report = check_plan(build_plan(problem, result, skymap, name), skymap, problem.config)
        assert report.ok, (name, report.problems)
        assert report.coverage <= bound.value + 2e-3, name  # the checker's coverage tolerance
        assert problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob) <= bound.value


def test_refined_bound_is_above_the_exact_optimum_on_grid_and_outer_windows(map_220722v):
    _, full = map_220722v
    problem = reduced_problem(full, 8)
    grid = solve_exact(problem, time_limit_s=60.0)
    outer = solve_exact(refined_problem(problem, "outer"), time_limit_s=60.0, starts=(grid.result.observations,))
    assert grid.proven and outer.proven
    value = interval_upper_bound(problem, time_limit_s=10.0).value
    assert value >= outer.optimum - 1e-9 >= grid.optimum - 2e-9


@pytest.mark.skipif(not BNS_14.is_file(), reason="shared sky maps not present")
def test_refined_bound_is_strictly_tighter_where_windows_end_inside_the_step():
    """bns_o3/14, top 20 fields: every window ends at the horizon and starts as its field rises, so the
    one-step widening lets two more fields in; the outer windows do not (V 0.634 -> 0.560 when written)."""
    _, full = _problem(BNS_14)
    problem = reduced_problem(full, 20)
    coarse = interval_upper_bound(problem, time_limit_s=10.0)
    fine = interval_upper_bound(_refined(problem), time_limit_s=10.0)
    assert fine.value < coarse.value - 0.01
    for name in ("greedy", "hybrid"):
        result = run_scheduler(_refined(problem), name)
        assert problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob) <= fine.value
    exact = solve_exact(problem, time_limit_s=20.0)
    assert exact.optimum <= fine.value
