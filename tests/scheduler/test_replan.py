"""Re-planning from now given the executed record (docs/design/replan.md, P1-P9), on a real map with the real solvers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from astropy.time import TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan
from mushrooms.scheduler_core.executed import ExecutedExposure, done_pairs
from mushrooms.scheduler_core.plan.document import Observation
from mushrooms.scheduler_core.replan import plan_remaining
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields

CFG = PlanningConfig(solver="greedy")


def executed_from(plan, n, fractions=None, status=None):
    """The first ``n`` exposures of a plan as the telescope did them (all reduced unless told)."""
    fractions, status = fractions or {}, status or {}
    out = []
    for i, o in enumerate(plan.observations[:n]):
        out.append(ExecutedExposure(o.field_id, o.filter, plan.absolute_time(o.start), o.exposure_s,
                                    fractions.get(i, 1.0), status.get(i, "processed")))
    return out


@pytest.fixture(scope="module")
def first_plan(skymap_220722v):
    return make_plan(skymap_220722v, CFG)


def seconds(plan, t):
    return float((t - plan.start).to_value("s"))


def assert_replan_rules(replan, executed, skymap, config):
    """What every re-plan must hold: checked, no exposure before its start, no repeat of a done pair,
    the half-done fields' other filter at least the cadence after the first, honest coverage."""
    report = check_plan(replan, skymap, config, executed=executed)
    assert report.ok, report.problems
    assert all(o.start >= 0 for o in replan.observations)
    pairs = done_pairs(executed, config.filters, cadence_s=config.cadence_s)
    planned = {o.field_id for o in replan.observations}
    assert not planned & set(pairs.both)
    for fid, visits in pairs.one.items():
        mine = [o for o in replan.observations if o.field_id == fid]
        if not mine:
            continue
        first = visits.filters[0]
        other = [o for o in mine if o.filter != first]
        assert other, f"half-done field {fid} planned without its other filter"
        done_first_s = seconds(replan, visits.first[first])
        whole_new_pair = len({o.filter for o in mine}) == 2
        assert whole_new_pair or min(o.start for o in other) >= done_first_s + config.cadence_s - 1e-6
    fp = field_footprints(load_ztf_fields(), config.nside)
    assert replan.metrics.coverage_executed == pytest.approx(fp.coverage(list(pairs.both), skymap.prob), abs=1e-6)
    total = fp.coverage(list(planned | set(pairs.both)), skymap.prob)
    assert replan.metrics.coverage + replan.metrics.coverage_executed == pytest.approx(total, abs=1e-5)


@pytest.mark.parametrize("solver", ["greedy", "hybrid"])
def test_a_replan_after_a_two_hour_closure_completes_the_half_done_fields(first_plan, skymap_220722v, solver):
    executed = executed_from(first_plan, 10)
    pairs = done_pairs(executed, CFG.filters, cadence_s=CFG.cadence_s)
    assert pairs.both and pairs.one  # the scenario has both kinds
    config = dataclasses.replace(CFG, solver=solver, time_limit_s=10.0)
    start = executed[-1].end + TimeDelta(2 * 3600, format="sec")
    replan = plan_remaining(skymap_220722v, config, start, executed, solver=solver)
    assert abs(seconds(first_plan, replan.start) - seconds(first_plan, start)) < 1e-3
    assert_replan_rules(replan, executed, skymap_220722v, config)
    print(solver, replan.metrics, [(o.field_id, o.filter, round(o.start)) for o in replan.observations[:6]])


def test_half_done_fields_get_their_other_filter_first_and_failed_exposures_do_not_count(first_plan, skymap_220722v):
    # the 7th exposure (a second-filter one) failed, the 8th was only partly reduced: their fields are half done
    executed = executed_from(first_plan, 10, fractions={6: 0.0, 7: 0.3}, status={6: "failed"})
    pairs = done_pairs(executed, CFG.filters, cadence_s=CFG.cadence_s)
    for i in (6, 7):
        assert executed[i].field_id in pairs.one and executed[i].field_id not in pairs.both
    start = executed[-1].end + TimeDelta(45 * 60, format="sec")
    replan = plan_remaining(skymap_220722v, CFG, start, executed)
    assert_replan_rules(replan, executed, skymap_220722v, CFG)
    print(replan.metrics, [(o.field_id, o.filter, round(o.start)) for o in replan.observations[:8]])
    half = set(pairs.one)
    lead = []
    for o in replan.observations:
        if o.field_id not in half:
            break
        lead.append(o)
    # the half-done fields observable at the start are completed first, each by one exposure in its other filter
    assert len(lead) >= 2 and len({o.field_id for o in lead}) == len(lead)
    for o in lead:
        assert o.filter != pairs.one[o.field_id].filters[0]
    assert replan.observations[0].start <= CFG.exposure_s + CFG.slew_estimate_s
