"""The published certified bound min(U4, V) and the portfolio that stops once a plan reaches it."""

from __future__ import annotations

import dataclasses
import logging
import re

import pytest
from astropy.time import Time

from test_interval_bound import _crowded_problem
from tests_paths import MAP_220722V
from mushrooms.evaluation.reduced import reduced_problem
from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.schedulers.portfolio.portfolio import Portfolio, hybrid, reaches_bound


def _with(problem, **changes):
    return dataclasses.replace(problem, config=dataclasses.replace(problem.config, **changes))


def test_budget_zero_publishes_the_online_bound_exactly():
    problem = _with(_crowded_problem(), bound_time_limit_s=0.0)
    u4 = coverage_upper_bound(problem)
    got = certified_upper_bound(problem)
    assert (got.value, got.status, got.method) == (u4.value, u4.status, "online")
    # through the schedulers too: the plan's bound is U4 with the budget 0
    result = run_scheduler(problem, "slots")
    assert result.upper_bound.value == u4.value and result.upper_bound.method == "online"


def test_the_published_bound_is_the_interval_bound_where_it_is_lower():
    problem = _crowded_problem()  # U4 = .74 (all four fields), V = .62 (only two of fields 1-3 fit)
    u4 = coverage_upper_bound(problem)
    got = certified_upper_bound(problem)
    assert got.value < u4.value
    assert got.value == pytest.approx(0.62, abs=1e-6)
    assert got.method == "interval"
    for solver in ("slots", "blocks", "hybrid"):
        result = run_scheduler(problem, solver)
        assert result.upper_bound.method == "interval", solver
        assert published_coverage(problem, result) <= result.upper_bound.value + 1e-9 <= u4.value + 1e-9, solver


def test_the_bound_budget_is_validated():
    with pytest.raises(ValueError, match="bound_time_limit_s"):
        PlanningConfig(bound_time_limit_s=-1.0)
    assert PlanningConfig(bound_time_limit_s=0.0).bound_time_limit_s == 0.0


@pytest.fixture(scope="module")
def greedy_optimal_problem():
    """MS220722v reduced to its top 8 fields: the night holds all 8, and greedy plans them all."""
    cfg = PlanningConfig(time_limit_s=3.0, milp_backend="highs", min_gain=0.0, min_coverage=0.0,
                         objective="coverage", threads=1)
    skymap = read_skymap(MAP_220722V, nside=cfg.nside)
    return skymap, reduced_problem(prepare_problem(skymap, cfg, Time(skymap.event_time, scale="utc")), 8)


def test_hybrid_stops_when_greedy_reaches_the_bound_and_keeps_the_same_plan(greedy_optimal_problem, caplog):
    skymap, problem = greedy_optimal_problem
    bound = certified_upper_bound(problem)
    greedy = run_scheduler(problem, "greedy")
    assert reaches_bound(published_coverage(problem, greedy), bound)  # the premise: greedy is optimal here
    with caplog.at_level(logging.INFO, logger="mushrooms.scheduler_core.schedulers.portfolio.portfolio"):
        stopped = run_scheduler(problem, "hybrid")
    assert stopped.details["skipped_at_bound"] == ["slots", "slots_paced", "lns"]  # blocks: off (hybrid_blocks)
    assert [e.name for e in stopped.portfolio] == ["greedy"]
    assert re.search(r"it is optimal, skipping slots, slots_paced, lns$", caplog.text, re.M)
    assert stopped.upper_bound.value == pytest.approx(bound.value, abs=1e-9)
    # the same portfolio without the bound runs on (blocks too when 3 s are left) and keeps the same plan
    full = Portfolio("hybrid", hybrid.stages)(problem)
    assert [e.name for e in full.portfolio][:2] == ["greedy", "slots"]
    assert full.portfolio_choice == stopped.portfolio_choice == "greedy"
    assert full.observations == stopped.observations
    a = build_plan(problem, stopped, skymap, "hybrid")
    b = build_plan(problem, dataclasses.replace(full, upper_bound=stopped.upper_bound), skymap, "hybrid")
    assert a.observations == b.observations and a.metrics.coverage == b.metrics.coverage
    assert a.metrics.coverage <= a.metrics.upper_bound


def test_the_stages_skipped_at_the_bound_are_those_the_config_would_have_run(greedy_optimal_problem):
    skymap, problem = greedy_optimal_problem
    with_blocks = dataclasses.replace(problem, config=dataclasses.replace(problem.config, hybrid_blocks=True))
    assert run_scheduler(with_blocks, "hybrid").details["skipped_at_bound"] == ["slots", "slots_paced", "lns", "blocks"]
    bare = dataclasses.replace(problem, config=dataclasses.replace(problem.config, hybrid_paced_slots=False,
                                                                   hybrid_lns=False))
    assert run_scheduler(bare, "hybrid").details["skipped_at_bound"] == ["slots"]


def test_hybrid_runs_on_until_a_stage_reaches_the_bound():
    # greedy is below V = .62 here; the slot portfolio reaches the optimum .62, so the stages after it are skipped
    problem = _crowded_problem()
    result = run_scheduler(problem, "hybrid")
    covs = {e.name: e.coverage for e in result.portfolio}
    assert not reaches_bound(covs["greedy"], result.upper_bound)
    assert list(covs) == ["greedy", "slots"]
    assert reaches_bound(covs["slots"], result.upper_bound)
    assert result.details["skipped_at_bound"] == ["slots_paced", "lns"]
    assert result.portfolio_choice == "slots"


def test_the_interval_bound_after_a_solve_of_the_process_thread_setting():
    # HiGHS sizes one thread pool per process: the bound's solves follow config.threads, so a slot solve
    # before it (threads = 0: the solver decides) leaves it valid, never a failed solve's zero "bound"
    problem = _crowded_problem()
    assert problem.config.threads == 0
    run_scheduler(_with(problem, bound_time_limit_s=0.0), "slots")
    got = certified_upper_bound(problem)
    assert got.method == "interval" and got.value == pytest.approx(0.62, abs=1e-6)
    # another thread count in the same process: the solver resets its pool, the solves stay valid
    for threads in (1, 0):
        other = _with(problem, threads=threads)
        assert certified_upper_bound(other).value == pytest.approx(0.62, abs=1e-6), threads
        assert run_scheduler(_with(other, bound_time_limit_s=0.0), "slots").status == "optimal", threads
