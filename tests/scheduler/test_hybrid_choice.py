"""The hybrid compares its candidates as they will be published: after the least-gain rule."""

from __future__ import annotations

import dataclasses

from astropy.time import Time

from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.planner import build_plan, run_scheduler
from mushrooms.scheduler_core.prepare import prepare_problem


def test_the_coverage_the_hybrid_compares_is_the_published_coverage(skymap_220722v):
    cfg = PlanningConfig(min_gain=0.003, time_limit_s=2.0, milp_backend="highs", objective="coverage",
                         deterministic=True)
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    greedy = run_scheduler(problem, "greedy")
    raw = problem.footprints.coverage({o.field_id for o in greedy.observations}, problem.prob)
    plan = build_plan(problem, greedy, skymap_220722v, "greedy")
    assert plan.metrics.n_fields < len({o.field_id for o in greedy.observations})  # the rule dropped fields
    assert plan.metrics.coverage < raw
    assert abs(published_coverage(problem, greedy) - plan.metrics.coverage) < 1e-6
    hybrid = build_plan(problem, run_scheduler(problem, "hybrid"), skymap_220722v, "hybrid")
    assert hybrid.metrics.coverage >= plan.metrics.coverage - 1e-6
    # without the rule nothing is dropped and both coverages agree
    cfg0 = dataclasses.replace(cfg, min_gain=0.0)
    p0 = dataclasses.replace(problem, config=cfg0)
    assert abs(published_coverage(p0, greedy) - raw) < 1e-12


def test_hybrid_under_a_detection_config_gives_its_blocks_stage_what_is_left(skymap_220722v, monkeypatch):
    """run_scheduler with the default objective (detection): the blocks MILP's budget may be shorter than
    the detection stage's share (found by `mushrooms study`: 'detection_time_limit_s (4 s) must be less
    than time_limit_s (3.65 s)'); the blocks stage is a coverage scheduler and must still run."""
    import mushrooms.scheduler_core.schedulers.portfolio.lns as lns_module
    import mushrooms.scheduler_core.schedulers.slots.schedule as slot_module

    real = slot_module.slot_schedule
    real_lns = lns_module.lns_improve
    # the LNS stage after the slots gets 0.5 s, so that more than MIN_BLOCKS_S is left for blocks
    monkeypatch.setattr(lns_module, "lns_improve", lambda problem, seed, should_stop=None, time_limit_s=None, **_:
                        real_lns(problem, seed, should_stop, time_limit_s=0.5))
    monkeypatch.setattr(slot_module, "slot_schedule",
                        lambda problem, should_stop=None, start=None, time_limit_s=None:
                        real(problem, should_stop, start=start, time_limit_s=0.5))
    cfg = PlanningConfig(time_limit_s=8.0, detection_time_limit_s=7.99, milp_backend="highs", objective="detection",
                         hybrid_blocks=True, deterministic=True)
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    result = run_scheduler(problem, "hybrid")
    assert "blocks" in [e.name for e in result.portfolio]  # > MIN_BLOCKS_S was left, < 7.99 s
    assert result.observations


def test_the_hybrid_runs_its_block_stage_only_when_asked_and_a_plan_records_the_key_only_then(skymap_220722v):
    """hybrid_blocks (default false): the block MILP is not in the portfolio, and the config a plan records
    (and its plan id hashes) is the one from before the key existed."""
    from mushrooms.scheduler_core.schedulers.portfolio import portfolio

    cfg = PlanningConfig(time_limit_s=4.0, milp_backend="highs", objective="coverage", deterministic=True)
    assert "blocks" in [s.name for s in portfolio.hybrid.stages]
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    assert [e.name for e in run_scheduler(problem, "hybrid").portfolio] == ["greedy", "slots", "slots_paced", "lns"]
    assert "hybrid_blocks" not in cfg.record()
    assert PlanningConfig(hybrid_blocks=True).record()["hybrid_blocks"] is True


def test_the_stage_times_name_every_stage_that_ran_in_order(skymap_220722v, caplog):
    # `mushrooms plan` logs where its seconds go, from the result's details
    import logging

    from mushrooms.scheduler_core.planner import make_plan, optimise

    cfg = PlanningConfig(time_limit_s=3.0, detection_time_limit_s=1.0, milp_backend="highs", objective="detection",
                         deterministic=True)
    problem = prepare_problem(skymap_220722v, cfg, Time(skymap_220722v.event_time, scale="utc"))
    result = optimise(problem, skymap_220722v, "hybrid")
    times = result.details["stage_times_s"]
    ran = [e.name for e in result.portfolio]
    assert list(times) == [ran[0], "bound", *ran[1:], "detection"]
    assert all(t >= 0 for t in times.values())
    with caplog.at_level(logging.INFO, logger="mushrooms.scheduler_core.planner"):
        make_plan(skymap_220722v, dataclasses.replace(cfg, objective="coverage"), solver="greedy",
                  times_before={"load": 1.25})
    line = next(r.getMessage() for r in caplog.records if r.getMessage().startswith("times: "))
    assert line.startswith("times: load 1.25 s, prepare ") and ", greedy " in line and ", checker " in line
