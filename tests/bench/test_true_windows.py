"""Window ends refined below the grid step (evaluation/true_windows.py), on a real map with the real checker."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from astropy.time import Time

from mushrooms.evaluation.exact import solve_exact
from mushrooms.evaluation.reduced import reduced_problem
from mushrooms.evaluation.true_windows import refined_problem, refined_windows
from mushrooms.scheduler_core import PlanningConfig, check_plan, prepare_problem, read_skymap
from mushrooms.scheduler_core.planner import build_plan
from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound

MAP_220722V = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


@pytest.fixture(scope="module")
def full_220722v():
    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=3.0, milp_backend="highs", min_gain=0.0,
                         min_coverage=0.0)
    skymap = read_skymap(MAP_220722V, nside=cfg.nside)
    return skymap, prepare_problem(skymap, cfg, Time(skymap.event_time, scale="utc"))


def test_refined_ends_lie_between_the_grid_window_and_one_step_out(full_220722v):
    _, problem = full_220722v
    w, step, H = problem.windows, problem.config.time_step_s, problem.horizon_s
    fi, inner_a, inner_b = refined_windows(problem, "inner")
    fo, outer_a, outer_b = refined_windows(problem, "outer")
    assert np.array_equal(fi, w.field_ids) and np.array_equal(fo, w.field_ids)
    assert np.all(inner_a <= w.start + 1e-9) and np.all(inner_b >= w.end - 1e-9)
    assert np.all(outer_a <= inner_a + 1e-9) and np.all(outer_b >= inner_b - 1e-9)
    assert np.all(outer_a >= np.clip(w.start - step, 0, H) - 1e-9) and np.all(outer_b <= np.clip(w.end + step, 0, H) + 1e-9)
    # the refinement is not the one-step widening: a good share of the interior ends stop inside the step
    interior = (w.start - step > 0) & (w.end + step < H)
    ext = np.concatenate([(w.start - outer_a)[interior], (outer_b - w.end)[interior]])
    assert np.mean(ext < step - 1e-6) > 0.2 and ext.mean() < 0.9 * step


def test_exact_plan_on_inner_windows_passes_the_checker_and_outer_optimum_is_below_the_interval_bound(full_220722v):
    skymap, full = full_220722v
    problem = reduced_problem(full, 8)
    grid = solve_exact(problem, time_limit_s=60.0)
    inner = solve_exact(refined_problem(problem, "inner"), time_limit_s=60.0, starts=(grid.result.observations,))
    outer = solve_exact(refined_problem(problem, "outer"), time_limit_s=60.0, starts=(inner.result.observations,))
    assert grid.proven and inner.proven and outer.proven
    # the plan on the inner windows is rule-abiding: the independent checker recomputes the sky
    plan = build_plan(problem, inner.result, skymap, "hybrid")
    report = check_plan(plan, skymap, problem.config)
    assert report.ok, report.problems
    assert grid.optimum - 1e-9 <= inner.optimum <= outer.optimum + 1e-9
    # V widens by one whole step, outer by less: V bounds the outer optimum
    assert interval_upper_bound(problem, time_limit_s=10.0).value >= outer.optimum - 1e-9
