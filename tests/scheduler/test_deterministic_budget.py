"""The deterministic budget (``[scheduler] deterministic``, ``docs/design/milp.md`` A1-A5): a plan depends only on its
inputs and the configuration, not on how fast the machine runs."""

from __future__ import annotations

import dataclasses
import json
import time

import numpy as np
import pytest
import scipy.sparse as sp

from mushrooms.scheduler_core import PlanningConfig, make_plan, prepare_problem
from mushrooms.scheduler_core.budget import TICKS_PER_S, WorkClock, highs_work
from mushrooms.scheduler_core.plan.document import TIMING_FIELDS, without_timing
from mushrooms.scheduler_core.planner import build_plan, optimise
from mushrooms.scheduler_core.schedulers.milp.solvers import MilpModel, solve_milp

#: A budget small enough for a test, on the test map at nside 64: every hybrid stage and the detection stage run,
#: and the detection stage's budget ends before its last grids ("no time left").
SMALL = dict(nside=64, milp_backend="highs", time_limit_s=3.0, detection_time_limit_s=1.0, bound_time_limit_s=1.0)


def _knapsack(n: int, seed: int) -> MilpModel:
    """A knapsack HiGHS takes about 40 s to prove (n 200, seed 5): any short budget stops it mid-search."""
    rng = np.random.default_rng(seed)
    A = sp.csr_matrix(rng.integers(5, 60, (6, n)).astype(float))
    return MilpModel(rng.integers(5, 60, n).astype(float), A, np.full(6, -np.inf), A.sum(axis=1).A1 / 3,
                     np.zeros(n), np.ones(n), np.ones(n, bool))


def _slow_wall_clock(monkeypatch, factor: float = 10.0) -> None:
    """Every ``time.perf_counter()`` reading from now on runs ``factor`` times faster: the machine looks that slow."""
    real = time.perf_counter
    t0 = real()
    monkeypatch.setattr(time, "perf_counter", lambda: t0 + factor * (real() - t0))


def test_a_solve_on_the_work_clock_stops_at_its_work_whatever_the_wall_clock_says(monkeypatch):
    model = _knapsack(200, seed=5)
    first = WorkClock()
    a = solve_milp(model, "highs", 0.2, mip_gap=0.0, clock=first)
    _slow_wall_clock(monkeypatch)
    second = WorkClock()
    b = solve_milp(model, "highs", 0.2, mip_gap=0.0, threads=2, clock=second)  # (A4) one thread all the same
    assert a.status == b.status == "work_limit"
    assert np.array_equal(a.x, b.x) and a.objective == b.objective and a.bound == b.bound
    # (A2) charged the work it did, with its real LP iterations: about its limit, the same in both runs
    assert first.ticks == second.ticks and 0.15 * TICKS_PER_S < first.ticks < 0.3 * TICKS_PER_S
    assert highs_work(model.A.nnz, model.n_rows + model.n_vars, 10, iterations=10**6) > \
        highs_work(model.A.nnz, model.n_rows + model.n_vars, 10, iterations=0)  # its LP iterations are charged


def test_gurobi_on_the_work_clock_stops_at_its_own_work_limit_and_is_charged_its_work():
    model = _knapsack(200, seed=5)  # within the pip licence's 2000 variables
    runs = [(WorkClock(), None), (WorkClock(), None)]
    runs = [(c, solve_milp(model, "gurobi", 0.2, mip_gap=0.0, clock=c)) for c, _ in runs]
    (c1, a), (c2, b) = runs
    assert a.backend == b.backend == "gurobi" and a.status == b.status == "work_limit"
    assert np.array_equal(a.x, b.x) and c1.ticks == c2.ticks >= 0.2 * TICKS_PER_S


def test_a_solve_on_the_wall_clock_keeps_its_time_limit():
    res = solve_milp(_knapsack(200, seed=5), "highs", 0.5, mip_gap=0.0)  # no clock: the wall clock of before
    assert res.status == "time_limit"


@pytest.fixture(scope="module")
def test_map():
    from mushrooms.scheduler_core import read_skymap
    from tests_paths import MAP_220722V

    return read_skymap(MAP_220722V, nside=SMALL["nside"])


def test_two_plans_of_one_input_are_one_document_though_one_ran_ten_times_slower(test_map, monkeypatch):
    cfg = PlanningConfig(**SMALL, deterministic=True)
    quick = make_plan(test_map, cfg).to_document()
    _slow_wall_clock(monkeypatch)
    slow = make_plan(test_map, cfg).to_document()
    assert quick["metrics"]["runtime_s"] < slow["metrics"]["runtime_s"]  # the wall clock did run slower
    assert without_timing(quick) == without_timing(slow)
    assert json.dumps(without_timing(quick), sort_keys=True) == json.dumps(without_timing(slow), sort_keys=True)
    budget = quick["metrics"]["budget"]
    assert budget["kind"] == "work" and budget["unit"] == "work_s" and not budget["interrupted"]
    assert 0 < budget["spent"] and quick["config"]["deterministic"] is True
    assert quick["metrics"]["solver"].startswith("detection(hybrid(")  # the whole optimisation ran
    assert set(TIMING_FIELDS) == {"created", "metrics.runtime_s", "metrics.latency_s"}


def test_a_wall_clock_stop_still_ends_a_work_budget_and_the_document_says_so(test_map):
    cfg = PlanningConfig(**SMALL, deterministic=True)
    problem = prepare_problem(test_map, cfg, test_map.event_time)
    calls = []
    result = optimise(problem, test_map, "hybrid", should_stop=lambda: len(calls) > 3 or calls.append(1))
    budget = build_plan(problem, result, test_map, "hybrid").to_document()["metrics"]["budget"]
    assert budget["kind"] == "work" and budget["interrupted"] is True


def test_the_wall_budget_of_before_records_no_key_and_says_wall(test_map):
    cfg = PlanningConfig(**SMALL, deterministic=False)
    assert "deterministic" not in cfg.record()  # plans on the wall budget keep the plan ids of before
    assert PlanningConfig(deterministic=True).record()["deterministic"] is True
    problem = prepare_problem(test_map, cfg, test_map.event_time)
    result = optimise(problem, test_map, "hybrid")
    assert result.details["budget"] == {"kind": "wall", "unit": "s", "interrupted": False}
    greedy = build_plan(problem, optimise(problem, test_map, "greedy"), test_map, "greedy")
    assert greedy.metrics.budget is None  # greedy has no budget


def test_a_problem_derived_from_another_shares_its_clock_and_the_bound_is_off_its_budget(test_map):
    from mushrooms.scheduler_core.schedulers.portfolio.portfolio import published_bound

    problem = prepare_problem(test_map, PlanningConfig(**SMALL, deterministic=True), test_map.event_time)
    derived = dataclasses.replace(problem, config=dataclasses.replace(problem.config, objective="coverage"))
    assert derived.clock is problem.clock and isinstance(problem.clock, WorkClock)
    mark = problem.clock.mark()
    published_bound(problem)
    assert problem.clock.ticks > mark[0] and problem.clock.since(mark) == 0.0  # (A1) charged, but off the budget


def test_bench_and_study_plan_on_the_work_budget(tmp_path):
    import argparse

    from mushrooms.tool.bench import bench_settings
    from mushrooms.tool.config import Config

    args = argparse.Namespace(solvers="greedy,hybrid", injections=10, jobs=1, start=None, arm=None)
    wall = Config.from_mapping({"scheduler": {"deterministic": False}}, source="c.toml")
    assert wall.scheduler.deterministic is False
    assert bench_settings(args, wall).config.deterministic is True

