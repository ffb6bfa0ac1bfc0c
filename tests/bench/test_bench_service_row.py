"""The ``service`` row (what the daemon publishes: the anytime flow) and every row's coverage as executed."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from mushrooms.evaluation.bench import BenchConfig, BenchSettings, run_bench
from mushrooms.evaluation.bench.scoring import execution_cells_under
from mushrooms.evaluation.study.graph import plan_and_score
from mushrooms.evaluation.study.store import study_config
from mushrooms.scheduler_core.config import PlanningConfig

FAST = PlanningConfig(solver="hybrid", objective="coverage", nside=64, threads=1, time_limit_s=2.0, deterministic=True)
SCORING = BenchConfig(legacy_scoring=False)


@pytest.fixture
def skymap(data_dir):
    return data_dir / "skymaps" / "MS220722v_bayestar.multiorder.fits"


def _rows(skymap, config=FAST, gain=0.005, solvers=("greedy", "service")):
    settings = BenchSettings(config=config, bench=SCORING, solvers=solvers, n_injections=300,
                             supersede_min_gain=gain)
    return {r["solver"]: r for r in run_bench(settings, [skymap])}


def test_the_fast_plan_stands_when_the_optimised_one_is_not_better_by_the_margin(skymap) -> None:
    rows = _rows(skymap, gain=1.0)  # no plan can cover 100 % more: revision 1 stands
    greedy, service = rows["greedy"], rows["service"]
    assert service["solver_detail"].startswith("revision 1 (greedy) stands: hybrid not better by 1")
    assert service["valid"] is True and service["status"] == "greedy"
    for key in ("coverage", "n_exposures", "efficiency_optimistic", "coverage_as_executed"):
        assert service[key] == greedy[key]
    assert service["runtime_s"] > greedy["runtime_s"]  # the optimisation ran all the same


def test_the_optimised_plan_is_published_when_it_covers_more(skymap) -> None:
    rows = _rows(skymap, gain=0.0, solvers=("greedy", "hybrid", "service"))
    greedy, hybrid, service = rows["greedy"], rows["hybrid"], rows["service"]
    assert service["valid"] is True and service["objective"] == "coverage"
    if service["solver_detail"].startswith("revision 2 (hybrid)"):
        assert service["coverage"] > greedy["coverage"]
    else:  # the hybrid tied the greedy plan on this small map
        assert service["solver_detail"].startswith("revision 1 (greedy) stands")
        assert service["coverage"] == greedy["coverage"] and hybrid["coverage"] <= greedy["coverage"] + 1e-6


def test_below_min_coverage_the_service_answers_not_observable_and_scores_nothing(skymap) -> None:
    rows = _rows(skymap, config=dataclasses.replace(FAST, min_coverage=0.99))
    greedy, service = rows["greedy"], rows["service"]
    assert greedy["coverage"] > 0 and greedy["n_exposures"] > 0  # the scheduler's own row is unchanged
    assert service["status"] == "not_observable" and service["valid"] is True
    assert service["coverage"] == 0.0 and service["n_exposures"] == 0 and service["coverage_as_executed"] == 0.0
    assert service["efficiency_optimistic"] == 0.0 and service["efficiency_nsbh"] == 0.0
    assert service["note"]  # the answer's reasons, in words


def test_every_row_has_its_coverage_as_executed_and_a_plan_without_it_gets_the_same_number(skymap) -> None:
    from mushrooms.scheduler_core import make_plan
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    rows = _rows(skymap, solvers=("greedy", "hybrid", "service"))
    for row in rows.values():
        assert 0.0 < row["coverage_as_executed"] <= row["coverage"] + 1e-6
    sky = read_skymap(skymap, nside=64)
    from astropy.time import Time

    plan = make_plan(sky, dataclasses.replace(FAST, solver="greedy"),
                     start=Time(rows["greedy"]["start"].rstrip("Z"), scale="utc"))
    assert plan.metrics.coverage_as_executed == pytest.approx(rows["greedy"]["coverage_as_executed"], abs=1e-6)
    footprints = field_footprints(load_ztf_fields(), 64)
    bare = plan.with_(config=None, metrics=dataclasses.replace(plan.metrics, coverage_as_executed=None))
    # a baseline's plan names no filters or cadence: the planning configuration's are used
    assert execution_cells_under(bare, FAST, footprints, sky.prob)["coverage_as_executed"] == pytest.approx(
        plan.metrics.coverage_as_executed, abs=1e-6)
    slow = dataclasses.replace(FAST, cadence_s=6 * 3600.0)  # pairs must now be 6 h apart: fewer fields count
    assert execution_cells_under(bare, slow, footprints, sky.prob)["coverage_as_executed"] < plan.metrics.coverage_as_executed
    empty = bare.with_(observations=())
    assert execution_cells_under(empty, FAST, footprints, sky.prob)["coverage_as_executed"] == 0.0


def test_the_supersede_margin_comes_from_the_daemon_section_and_keys_the_study_results() -> None:
    from mushrooms.tool.bench import bench_settings
    from mushrooms.tool.config import Config

    args = argparse.Namespace(solvers="greedy,service", injections=100, start=None, arm=None)
    settings = bench_settings(args, Config.from_mapping({"daemon": {"supersede_min_gain": 0.02}}, source="c.toml"))
    assert settings.supersede_min_gain == 0.02 and settings.solvers == ("greedy", "service")
    assert bench_settings(args, Config()).supersede_min_gain == 0.005
    assert study_config(settings) != study_config(dataclasses.replace(settings, supersede_min_gain=0.005))
    with pytest.raises(ValueError, match="supersede_min_gain"):
        dataclasses.replace(settings, supersede_min_gain=2.0)
    with pytest.raises(ValueError, match="unknown solver"):
        BenchSettings(config=FAST, solvers=("services",))


def test_a_study_task_reports_its_cpu_time(skymap) -> None:
    settings = BenchSettings(config=dataclasses.replace(FAST, solver="greedy"), bench=SCORING,
                             solvers=("greedy",), n_injections=200)
    res = plan_and_score(str(skymap), "greedy", settings)
    assert res["ok"] and 0.0 < res["cpu_s"] and res["row"]["coverage_as_executed"] > 0
