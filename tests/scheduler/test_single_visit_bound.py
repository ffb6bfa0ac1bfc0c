"""A certified bound for single-visit plans (one filter: LS4's ``i``, WINTER's ``J``), U5-U6 and V8 of milp.md.

A plan whose sequence is one filter covers a field with one exposure, so the
pair's relaxations (U1: two exposures the cadence apart; U2: 2 exposures a
field) do not bound it.  U5 takes every field with a window holding one
exposure, U6 one exposure a field (K = the exposures the observable time
holds), V8 the interval rows with one role per field; the published bound is
min(U4, V) as for pairs (V5).  Before, such plans published no bound.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
from astropy.time import Time

from conftest_milp import crowded_problem, random_problem, tiny_config
from tests_paths import MAP_220722V
from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
from mushrooms.scheduler_core.instruments import load_description
from mushrooms.scheduler_core.planner import run_scheduler
from mushrooms.scheduler_core.problem import PlanningProblem
from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound, max_fields, pairable_rows
from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound, interval_violation
from mushrooms.scheduler_core.schedulers.gain import published_coverage

SHARED = Path("/work/shared/data/skymaps/public")
MAPS = {  # two southern, two northern
    "sim6": SHARED / "obs-scenarios_sim6_HKL.multiorder.fits",
    "G483432": SHARED / "G483432_bayestar.multiorder.fits",
    "S191216ap": SHARED / "S191216ap_bayestar.multiorder.fits",
    "MS220722v": MAP_220722V,
}


def _one_visit_crowded() -> PlanningProblem:
    """Three fields visible in [0, 200] s only, one in [1000, 1400] s; one filter, 100 s exposures.

    Widened by the 60 s step, [0, 260] s holds floor((260 + r) / (100 + r)) = 2 exposures (r = the
    readout, 8 s): two of fields 1-3.  Coverage: f1 = {0, 1} = .3, f2 = {2} = .22, f3 = {1, 3} = .22,
    f4 = {4} = .1; the best two of fields 1-3 are {1, 2} = .52, so the optimum is .62, all four .74.
    """
    return crowded_problem(200.0, filters=("g",))


def test_one_visit_counts_one_exposure_a_field_and_every_observable_field():
    problem = _one_visit_crowded()
    assert problem.config.slew.readout_s == 8.0
    assert sorted(problem.field_ids[pairable_rows(problem)].tolist()) == [1, 2, 3, 4]  # (U5) no cadence to keep
    # (U6) [0, 260] s: 2 exposures; [940, 1460] s: floor(528 / 108) = 4; one a field
    assert max_fields(problem, pairable_rows(problem)) == 6
    u4 = coverage_upper_bound(problem)
    assert u4.value == pytest.approx(0.74, abs=1e-9)  # every field: the night holds them all


def test_fields_competing_for_the_same_minutes_tighten_the_one_visit_bound():
    problem = _one_visit_crowded()
    v = interval_upper_bound(problem, time_limit_s=10.0)
    assert v.value == pytest.approx(0.62, abs=1e-6) and v.method == "interval"  # (V8) two of fields 1-3
    assert certified_upper_bound(problem).value == pytest.approx(0.62, abs=1e-6)
    for solver in ("greedy", "hybrid"):
        result = run_scheduler(problem, solver)
        assert published_coverage(problem, result) <= 0.62 + 1e-9, solver
        assert interval_violation(problem, {o.field_id for o in result.observations}) <= 1e-6, solver
    published = run_scheduler(problem, "hybrid").upper_bound  # (V5) the hybrid publishes it
    assert published is not None and published.value == pytest.approx(0.62, abs=1e-6)


@pytest.mark.parametrize("seed", range(6))
def test_the_one_visit_bound_is_above_every_plan_and_v_below_u4(seed):
    cfg = tiny_config(n_blocks_max=3, penalty=0.0, n_fields=None, horizon_h=1.0, filters=("r",), min_gain=0.0)
    problem = random_problem(seed, n_fields=18, config=cfg)
    u4 = coverage_upper_bound(problem)
    v = interval_upper_bound(problem, time_limit_s=10.0)
    assert v.value <= u4.value + 1e-9 and u4.value <= float(problem.prob.sum()) + 1e-9
    bound = certified_upper_bound(problem)
    assert bound.value <= u4.value + 1e-9
    for solver in ("greedy", "hybrid"):
        result = run_scheduler(problem, solver)
        assert published_coverage(problem, result) <= bound.value + 1e-9, solver
        assert interval_violation(problem, {o.field_id for o in result.observations}) <= 1e-6, solver
    assert run_scheduler(problem, "hybrid").upper_bound is not None


def test_a_pair_keeps_its_bound():
    """(F5) Two filters: the pair's rows, K = half the exposures; the one-visit rule touches only one filter."""
    pair = dataclasses.replace(_one_visit_crowded(), config=tiny_config(
        nside=1, horizon_h=0.5, time_step_s=60.0, penalty=0.0, n_fields=None, min_gain=0.0))
    assert pair.field_ids[pairable_rows(pair)].tolist() == [4]  # only field 4 holds two exposures 250 s apart
    assert max_fields(pair, pairable_rows(pair)) == 2  # floor(4 / 2)
    assert coverage_upper_bound(pair).value == pytest.approx(0.1, abs=1e-9)


@pytest.fixture(scope="module")
def skymaps():
    return {name: read_skymap(path, nside=64) for name, path in MAPS.items() if path.is_file()}


@pytest.mark.parametrize("telescope, name", [("ls4", "sim6"), ("ls4", "G483432"), ("ls4", "S191216ap"),
                                             ("ls4", "MS220722v"), ("winter", "MS220722v"),
                                             ("winter", "G483432")])
def test_a_single_visit_plan_publishes_a_bound_above_its_coverage(skymaps, telescope, name):
    if name not in skymaps:
        pytest.skip("the shared sky maps are not here")
    skymap = skymaps[name]
    cfg = PlanningConfig.for_telescope(load_description(telescope), {
        "nside": 64, "solver": "hybrid", "time_limit_s": 3.0, "detection_time_limit_s": 1.0,
        "bound_time_limit_s": 2.0})
    assert len(cfg.filters) == 1
    plan = make_plan(skymap, cfg, start=Time(skymap.event_time, scale="utc"))
    m = plan.metrics
    assert m.upper_bound is not None and math.isfinite(m.upper_bound), m
    assert m.coverage <= m.upper_bound <= 1.0 + 1e-9
    assert m.upper_bound_method in ("online", "interval")
