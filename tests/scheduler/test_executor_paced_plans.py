"""Plans for the telescope's executor: the hybrid's paced candidate (Q19) and the detection floor as executed (X10)."""

from __future__ import annotations

import dataclasses

import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, prepare_problem
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.schedulers.detection.stage import detection_stage
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.schedulers.portfolio.lns import plan_rule_problems
from mushrooms.scheduler_core.schedulers.portfolio.portfolio import paced_cadence, paced_slots_stage
from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverage_as_executed, queue_coverage
from mushrooms.scheduler_core.telescope.queue_windows import CADENCE_MARGIN_S


@pytest.fixture(scope="module")
def two_hour_night(skymap_220722v):
    """MS220722v with a 2 h horizon from 15 min before greedy's first exposure: plans are packed to its end.

    On the deterministic budget (work, not wall seconds): what the stages find, and so the premises below, do
    not depend on the machine's load.  (From 10 min before, no grid's plan solved to its gap was refused as
    executed: the premise rested on what a grid's time-limited solve had found by then.)
    """
    full = prepare_problem(skymap_220722v, PlanningConfig(milp_backend="highs", threads=1, deterministic=True),
                           Time(skymap_220722v.event_time, scale="utc"))
    first = min(o.start for o in run_scheduler(full, "greedy").observations)
    cfg = PlanningConfig(milp_backend="highs", threads=1, time_limit_s=6.0, detection_time_limit_s=3.0, horizon_h=2.0,
                         deterministic=True)
    return prepare_problem(skymap_220722v, cfg, full.start + TimeDelta(first - 900.0, format="sec"))


def _pair_gaps(observations) -> list[float]:
    starts: dict[int, list[float]] = {}
    for o in observations:
        starts.setdefault(o.field_id, []).append(o.start)
    return [abs(a - b) for a, b in starts.values()]


def test_the_paced_plan_keeps_every_pair_the_executor_margin_past_the_cadence_and_holds_every_rule(
        skymap_220722v, two_hour_night):
    problem = two_hour_night
    paced = paced_slots_stage(problem, None, {}, 1.5)
    assert paced.observations and paced.solver.startswith("slots_paced:")
    gaps = _pair_gaps(paced.observations)
    assert min(gaps) >= problem.config.cadence_s + CADENCE_MARGIN_S - 1e-6
    assert plan_rule_problems(problem, paced.observations) == []  # a plan of the real problem
    assert check_plan(build_plan(problem, paced, skymap_220722v, "hybrid"), skymap_220722v, problem.config).ok
    # what the executor opens a cadence + 120 s after each first visit, it runs in full here
    assert keyed_coverage_as_executed(problem, paced)[1] == pytest.approx(published_coverage(problem, paced), abs=1e-6)


def test_the_hybrid_weighs_its_paced_candidate_by_what_is_executed_and_the_switches_turn_stages_off(two_hour_night):
    problem = dataclasses.replace(two_hour_night, config=dataclasses.replace(two_hour_night.config,
                                                                             objective="coverage"))
    result = run_scheduler(problem, "hybrid")
    names = [e.name for e in result.portfolio]
    assert names[:3] == ["greedy", "slots", "slots_paced"]
    executed = result.details["coverage_as_executed"]
    # (Q15) the choice executes best among the candidates the executor ran on
    assert executed[result.portfolio_choice] == max(executed.values())
    off = dataclasses.replace(problem, config=dataclasses.replace(problem.config, hybrid_paced_slots=False,
                                                                  hybrid_lns=False))
    assert [e.name for e in run_scheduler(off, "hybrid").portfolio] == ["greedy", "slots"]
    # plans record a switch only away from the configuration plans had before it existed
    assert "hybrid_paced_slots" not in off.config.record() and off.config.record()["hybrid_lns"] is False
    assert problem.config.record()["hybrid_paced_slots"] is True and "hybrid_lns" not in problem.config.record()


def test_the_paced_candidate_is_skipped_for_a_sequence_of_three_filters(two_hour_night):
    grg = dataclasses.replace(two_hour_night, config=dataclasses.replace(
        two_hour_night.config, objective="coverage", filters=("g", "r", "g")))
    result = run_scheduler(grg, "hybrid")
    assert "slots_paced" not in [e.name for e in result.portfolio]
    assert "slots_paced" in result.details["skipped_for_sequence"]


def test_a_detection_plan_that_loses_pairs_as_executed_is_not_published(skymap_220722v, two_hour_night):
    problem = two_hour_night
    coverage = paced_slots_stage(problem, None, {}, 1.5)  # executes in full (above)
    cx0 = keyed_coverage_as_executed(problem, coverage)[1]
    floor = (1.0 - problem.config.detection_max_coverage_loss) * cx0
    result = detection_stage(problem, skymap_220722v, coverage, time_limit_s=3.0)
    refused = [g for g in result.detection.grids if g.get("above_executed_floor") is False]
    # a grid's plan had more expected detections and kept the floor as planned, but its pairs, packed at the
    # cadence to the night's end, lose their second visits as executed
    assert refused
    assert all(g["above_floor"] and g["coverage_as_executed"] < floor for g in refused)
    assert all(g["expected_detections"] > result.detection.expected_detections_coverage for g in refused)
    plan = build_plan(problem, result, skymap_220722v, "hybrid")
    executed = queue_coverage(plan, problem.footprints, problem.prob)
    assert executed >= floor - 1e-9
    assert plan.metrics.coverage_as_executed == pytest.approx(executed, abs=1e-6)


def test_a_pair_span_caps_the_paced_cadence_and_one_at_the_cadence_leaves_no_paced_candidate(two_hour_night):
    cfg = dataclasses.replace(two_hour_night.config, objective="coverage", pair_max_s=1860.0)
    assert paced_cadence(cfg) == 1860.0  # the pairs stay pairs of the problem (its config would refuse more)
    capped = dataclasses.replace(two_hour_night, config=cfg)
    paced = paced_slots_stage(capped, None, {}, 1.5)
    assert paced.observations and min(_pair_gaps(paced.observations)) >= 1860.0 - 1e-6
    assert max(_pair_gaps(paced.observations)) <= 1860.0 + 1e-6
    plain = dataclasses.replace(two_hour_night, config=dataclasses.replace(cfg, pair_max_s=cfg.cadence_s))
    assert "slots_paced" not in [e.name for e in run_scheduler(plain, "hybrid").portfolio]
