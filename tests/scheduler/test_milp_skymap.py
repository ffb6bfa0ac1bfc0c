"""The MILP and the hybrid on a real sky map: checked plans, metrics, coverage >= greedy."""

from __future__ import annotations

import pytest

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan


@pytest.fixture(scope="module")
def milp_config() -> PlanningConfig:
    return PlanningConfig(time_limit_s=8.0, objective="coverage")  # the coverage schedulers themselves


@pytest.fixture(scope="module")
def milp_plan(skymap_220722v, milp_config):
    return make_plan(skymap_220722v, milp_config, solver="milp")


def test_milp_plan_passes_the_checker_and_reports_the_solver(milp_plan, skymap_220722v, milp_config):
    report = check_plan(milp_plan, skymap_220722v, milp_config)
    assert report.ok, report.problems
    m = milp_plan.metrics
    assert m.solver in ("milp:highs", "milp:gurobi")
    assert m.status in ("optimal", "time_limit", "work_limit")
    assert m.mip_gap is not None and 0 <= m.mip_gap < 0.5
    assert m.n_exposures == 2 * m.n_fields > 0
    assert report.coverage == pytest.approx(m.coverage, abs=2e-3)


def test_milp_blocks_repeat_fields_in_the_same_order(milp_plan, milp_config):
    f1, f2 = milp_config.filters
    blocks: dict[int, dict[str, list[int]]] = {}
    for o in milp_plan.observations:
        blocks.setdefault(o.block, {f1: [], f2: []})[o.filter].append(o.field_id)
    assert len(blocks) <= milp_config.n_blocks_max
    for b in blocks.values():
        assert b[f1] == b[f2]
        assert len(b[f1]) == len(set(b[f1]))


def test_hybrid_covers_at_least_the_greedy(skymap_220722v, milp_config, greedy_plan):
    hybrid = make_plan(skymap_220722v, milp_config, solver="hybrid")
    assert hybrid.metrics.coverage >= greedy_plan.metrics.coverage - 1e-9
    assert hybrid.metrics.solver.startswith("hybrid(")
    assert hybrid.metrics.status is not None
    assert check_plan(hybrid, skymap_220722v, milp_config).ok


def test_milp_plan_reports_a_bound_no_smaller_than_its_coverage(milp_plan, milp_config):
    m = milp_plan.metrics
    assert m.mip_bound is not None
    assert milp_config.penalty == 0.0  # then the objective is the covered probability
    assert m.coverage <= m.mip_bound + 1e-6
    doc = milp_plan.to_document()
    assert doc["metrics"]["mip_bound"] == m.mip_bound
