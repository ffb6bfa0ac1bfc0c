"""The greedy baseline: cadence, filters, order, and the checker's verdict."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan


def _visits(plan):
    by_field = defaultdict(dict)
    for o in plan.observations:
        assert o.filter not in by_field[o.field_id], "a field observed twice in one filter"
        by_field[o.field_id][o.filter] = o
    return by_field


def test_unchecked_greedy_schedule_passes_the_checker(skymap_220722v, greedy_plan, greedy_config):
    """The scheduler's own output, before make_plan's check, passes it (not true by construction)."""
    from mushrooms.scheduler_core import prepare_problem
    from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
    from mushrooms.scheduler_core.planner import build_plan

    problem = prepare_problem(skymap_220722v, greedy_config, greedy_plan.start)
    plan = build_plan(problem, greedy_schedule(problem), skymap_220722v, "greedy")
    report = check_plan(plan, skymap_220722v, greedy_config)
    assert report.ok, report.problems
    # the checker's footprints (great-circle CCD edges) and the schedulers' (projected plane) agree
    assert report.coverage == pytest.approx(plan.metrics.coverage, abs=2e-4)
    assert plan.metrics.n_exposures == 2 * plan.metrics.n_fields == len(plan.observations)


def test_a_plan_failing_the_checker_is_refused_by_make_plan(monkeypatch, skymap_220722v, greedy_config):
    import dataclasses

    import mushrooms.scheduler_core.planner as planner
    from mushrooms.scheduler_core.errors import PlanCheckError

    real = planner.run_scheduler

    def late_second_filter(problem, solver, should_stop=None):  # r visits 10 s short of the cadence
        result = real(problem, solver, should_stop)
        first = {}
        for o in result.observations:
            first.setdefault(o.field_id, o)
        moved = tuple(dataclasses.replace(o, start=first[o.field_id].start + problem.config.cadence_s - 10.0)
                      if o.filter == "r" and o.field_id == result.observations[0].field_id else o
                      for o in result.observations)
        return dataclasses.replace(result, observations=moved)

    monkeypatch.setattr(planner, "run_scheduler", late_second_filter)
    with pytest.raises(PlanCheckError) as info:
        make_plan(skymap_220722v, greedy_config)
    assert any(p.startswith("cadence: field ") and "1790 s apart" in p for p in info.value.problems)
    assert str(info.value).startswith("plan failed the checker: ")


def test_every_field_in_g_then_r_at_least_the_cadence_apart(greedy_plan, greedy_config):
    for fid, visits in _visits(greedy_plan).items():
        assert set(visits) == {"g", "r"}
        assert visits["r"].start - visits["g"].start >= greedy_config.cadence_s - 1e-6
        assert visits["g"].block == visits["r"].block


def test_blocks_repeat_the_same_fields_in_the_same_order(greedy_plan):
    blocks = defaultdict(lambda: defaultdict(list))
    for o in greedy_plan.observations:
        blocks[o.block][o.filter].append(o.field_id)
    for b in blocks.values():
        assert b["g"] == b["r"]


def test_longer_cadence_is_honoured(skymap_220722v):
    cfg = PlanningConfig(solver="greedy", cadence_s=3600.0)
    plan = make_plan(skymap_220722v, cfg)
    gaps = [v["r"].start - v["g"].start for v in _visits(plan).values()]
    assert min(gaps) >= 3600.0 - 1e-6
    assert check_plan(plan, skymap_220722v, cfg).ok


def test_greedy_picks_the_most_probable_field_first(greedy_plan, skymap_220722v):
    from mushrooms.scheduler_core import prepare_problem

    problem = prepare_problem(skymap_220722v, PlanningConfig(solver="greedy"), greedy_plan.start)
    first = greedy_plan.observations[0]
    observable_now = [f for f in problem.field_ids if problem.windows.contains(int(f), first.start, first.end)]
    probs = problem.footprints.field_probability(problem.prob)
    best = max(observable_now, key=lambda f: probs[problem.footprints.row(int(f))])
    assert first.field_id == best


def test_same_inputs_give_the_same_plan(skymap_220722v, greedy_plan, greedy_config):
    again = make_plan(skymap_220722v, greedy_config)
    assert again.plan_id == greedy_plan.plan_id
    assert again.observations == greedy_plan.observations and len(again.observations) > 0
    other = make_plan(skymap_220722v, PlanningConfig(solver="greedy", exposure_s=240.0))
    assert other.plan_id != greedy_plan.plan_id
