"""Not observable is an answer; no field is planned for less than the least gain."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mushrooms.bundled import demo_skymap_path
from mushrooms.scheduler_core import PlanningConfig, make_plan, not_observable, read_skymap
from mushrooms.scheduler_core.schedulers.gain import added_probability, drop_low_gain
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.planner import run_scheduler
from mushrooms.scheduler_core.plan.schema import validate_document

FAST = PlanningConfig(solver="greedy", nside=64, time_step_s=600.0)


@pytest.fixture(scope="module")
def sun_map():
    """MS181101ab, the mock BNS ~22 deg from the Sun at its merger time."""
    return read_skymap(demo_skymap_path(), nside=FAST.nside)


def test_a_map_next_to_the_sun_gets_a_not_observable_answer_with_measured_reasons(sun_map):
    plan = make_plan(sun_map, FAST)
    assert plan.metrics.coverage < FAST.min_coverage
    answer = not_observable(plan, sun_map, FAST)
    assert answer is not None
    sky = answer.reasons
    assert sky.daylight > 0.9  # the probability is up only in daylight
    assert sky.outside_limits + sky.daylight + sky.moon + sky.observable == pytest.approx(1.0, abs=1e-4)
    assert sky.night_h > 8 and sky.sun_separation_deg < 30
    assert "Sun" in answer.sentences[0]
    doc = answer.to_document()
    validate_document(doc)
    assert doc["type"] == "not_observable" and doc["plan_id"] == plan.plan_id
    assert doc["best_coverage"] == plan.metrics.coverage and doc["min_coverage"] == FAST.min_coverage
    assert doc["event"]["event_time"].startswith("2018-11-01T22:22") and "observations" not in doc


def test_with_thresholds_off_any_plan_with_fields_is_published(sun_map):
    loose = dataclasses.replace(FAST, min_coverage=0.0, min_gain=0.0)
    plan = make_plan(sun_map, loose)
    answer = not_observable(plan, sun_map, loose)
    # with every threshold off, a plan with fields is published however little it covers
    assert (answer is None) == bool(plan.observations)


def test_no_night_in_a_short_daytime_horizon(sun_map):
    # 2 h starting at Palomar noon (19:00 UTC): the Sun never sets
    from astropy.time import Time

    cfg = dataclasses.replace(FAST, horizon_h=2.0)
    plan = make_plan(sun_map, cfg, start=Time("2018-11-01T19:00:00", scale="utc"))
    answer = not_observable(plan, sun_map, cfg)
    assert answer is not None and answer.reasons.night_h == 0
    assert answer.sentences[0].startswith("no night in the horizon")


def test_an_observable_map_gets_a_plan():
    from tests_paths import MAP_220722V

    sm = read_skymap(MAP_220722V, nside=FAST.nside)
    plan = make_plan(sm, FAST)
    assert plan.metrics.coverage >= FAST.min_coverage and not_observable(plan, sm, FAST) is None


def test_least_gain_every_planned_field_adds_at_least_min_gain():
    from tests_paths import MAP_220722V

    sm = read_skymap(MAP_220722V, nside=FAST.nside)
    loose = dataclasses.replace(FAST, min_gain=0.0)
    problem = prepare_problem(sm, loose, sm.event_time)
    result = run_scheduler(problem, "greedy")
    order = list(dict.fromkeys(o.field_id for o in result.observations))
    gains = added_probability(order, problem.footprints, problem.prob)
    threshold = float(np.quantile(gains, 0.5))  # a threshold that must drop about half the fields
    kept = drop_low_gain(result, problem.footprints, problem.prob, threshold)
    kept_order = list(dict.fromkeys(o.field_id for o in kept.observations))
    assert 0 < len(kept_order) < len(order)
    assert set(kept.dropped_low_gain) == set(order) - set(kept_order)
    assert (added_probability(kept_order, problem.footprints, problem.prob) >= threshold).all()
    # both visits of a kept field stay, and no visit of a dropped one
    for fid in kept_order:
        assert sum(o.field_id == fid for o in kept.observations) == 2
    # the rule in make_plan: with the default least gain, every field adds at least 0.001
    plan = make_plan(sm, FAST)
    g = added_probability(plan.field_ids, problem.footprints, problem.prob)
    assert (g >= FAST.min_gain).all()
