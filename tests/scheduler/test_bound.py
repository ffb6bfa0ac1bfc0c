"""The certified coverage upper bound: above every plan, and above the relaxation's optimum."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy.time import Time

from tests_paths import MAP_FLAT_RING
from conftest_milp import random_problem, tiny_config
from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound, max_fields, pairable_rows
from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.sky.windows import Windows


def _coverage(problem, result) -> float:
    return problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob)


@pytest.mark.parametrize("seed", range(6))
def test_online_bound_is_above_the_relaxation_optimum_and_every_plan(seed):
    problem = random_problem(seed, n_fields=20, config=tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None,
                                                                    horizon_h=1.0, slot_positions=(1, 2, 3)))
    online = coverage_upper_bound(problem)
    exact = coverage_upper_bound(problem, method="milp")
    assert online.value >= exact.value - 1e-9
    for solver in ("greedy", "slots", "blocks"):
        assert _coverage(problem, run_scheduler(problem, solver)) <= exact.value + 1e-9


def test_pairable_fields_and_the_field_cap():
    problem = random_problem(0, config=tiny_config(horizon_h=1.0, n_fields=None))
    cfg = problem.config
    # one field visible for less than the cadence: it cannot hold a pair
    w = problem.windows
    start = w.start.copy()
    end = w.end.copy()
    k = np.flatnonzero(w.field_ids == problem.field_ids[0])
    start[k], end[k] = 0.0, cfg.exposure_s + 10.0
    p2 = dataclasses.replace(problem, windows=Windows(w.field_ids, start, end))
    assert 0 not in pairable_rows(p2)
    # a whole hour (widened windows clipped to it) holds floor((3600 + 8) / 108) = 33 exposures: 16 fields
    assert max_fields(p2, np.arange(len(p2.field_ids))) == (3600 + 8) // (cfg.exposure_s + 8) // 2


@pytest.fixture(scope="module")
def ring_problem():
    cfg = PlanningConfig(time_limit_s=3.0, milp_backend="highs", min_gain=0.0, objective="coverage")
    skymap = read_skymap(MAP_FLAT_RING, nside=cfg.nside)
    return skymap, prepare_problem(skymap, cfg, Time(skymap.event_time, scale="utc"))


def test_bound_is_above_every_plan_on_test_maps(ring_problem, skymap_220722v):
    cfg = PlanningConfig(time_limit_s=3.0, milp_backend="highs", min_gain=0.0, objective="coverage")
    p220722 = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    for skymap, problem in (ring_problem, (skymap_220722v, p220722)):
        ub = coverage_upper_bound(problem).value
        published = certified_upper_bound(problem)
        assert 0 < published.value <= ub + 1e-12  # min(U4, V) <= U4
        for solver in ("greedy", "slots", "blocks", "hybrid"):
            result = run_scheduler(problem, solver)
            plan = build_plan(problem, result, skymap, solver)
            assert plan.metrics.coverage <= published.value + 1e-9, solver
            if solver == "greedy":
                assert plan.metrics.upper_bound is None and plan.metrics.upper_bound_method is None
                continue
            # every optimising scheduler publishes min(U4, V) (V's time limit may land it a little
            # differently from this run) and says which bound it is
            assert plan.metrics.coverage <= plan.metrics.upper_bound <= round(ub, 6) + 1e-6, solver
            assert plan.metrics.upper_bound_method == result.upper_bound.method, solver
            assert result.upper_bound.method in ("online", "interval"), solver
            if result.upper_bound.method == "online":
                assert plan.metrics.upper_bound == pytest.approx(ub, abs=1e-6), solver
