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


@pytest.mark.parametrize("solver, n, delay_s", [("greedy", 10, 2 * 3600), ("hybrid", 10, 2 * 3600),
                                                ("greedy", 7, 60), ("hybrid", 7, 60)])
def test_a_replan_after_a_closure_or_a_slip_keeps_every_rule(first_plan, skymap_220722v, solver, n, delay_s):
    """2 h closed after the 10th exposure, or re-planned a minute after the 7th (half-done fields not all due yet)."""
    executed = executed_from(first_plan, n)
    pairs = done_pairs(executed, CFG.filters, cadence_s=CFG.cadence_s)
    assert pairs.both and pairs.one  # the scenario has both kinds
    config = dataclasses.replace(CFG, solver=solver, time_limit_s=10.0)
    start = executed[-1].end + TimeDelta(delay_s, format="sec")
    replan = plan_remaining(skymap_220722v, config, start, executed, solver=solver)
    assert abs(seconds(first_plan, replan.start) - seconds(first_plan, start)) < 1e-3
    assert_replan_rules(replan, executed, skymap_220722v, config)
    due = {v.field_id: seconds(replan, v.first[v.filters[0]]) + config.cadence_s for v in pairs.one.values()}
    if n == 7:
        assert max(due.values()) > 0  # some are not due at the start
    # every half-done field the plan completes with one exposure gets it once due, never before
    for fid, t_due in due.items():
        mine = [o for o in replan.observations if o.field_id == fid]
        if len(mine) == 1:
            assert mine[0].start >= t_due - 1e-6
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
    singles = [o for o in replan.observations if o.field_id in half]
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
    # each half-done field is completed by one exposure, or would add less than min_gain beside the plan
    assert len(singles) == len({o.field_id for o in singles})
    fp = field_footprints(load_ztf_fields(), CFG.nside)
    uncovered = skymap_220722v.prob.copy()
    uncovered[fp.union(list(pairs.both) + replan.field_ids)] = 0.0
    for fid in half - {o.field_id for o in singles}:
        assert uncovered[fp.pixels(fid)].sum() < CFG.min_gain


def test_the_checker_counts_executed_exposures_towards_pairs_and_refuses_repeats(first_plan, skymap_220722v):
    executed = executed_from(first_plan, 10)
    pairs = done_pairs(executed, CFG.filters, cadence_s=CFG.cadence_s)
    rest = first_plan.with_(observations=first_plan.observations[10:])
    # the rest of the original plan: its singles are the half-done fields' other filter, a cadence later
    report = check_plan(rest, skymap_220722v, CFG, executed=executed)
    assert report.counts.get("cadence", 0) == 0 and report.counts.get("repeat", 0) == 0
    # without the record those singles are half pairs
    assert check_plan(rest, skymap_220722v, CFG).counts.get("cadence", 0) == len(pairs.one)
    # two exposures of done pairs planned again
    again = first_plan.with_(observations=first_plan.observations[8:])
    assert check_plan(again, skymap_220722v, CFG, executed=executed).counts.get("repeat", 0) == 2
    # a half-done field's first exposure moved to just before its planned other filter: the cadence is broken
    fid = next(iter(pairs.one))
    planned = next(o for o in rest.observations if o.field_id == fid)
    moved = [dataclasses.replace(e, start=rest.absolute_time(planned.start - 600.0)) if e.field_id == fid else e
             for e in executed]
    broken = check_plan(rest, skymap_220722v, CFG, executed=moved)
    assert broken.counts.get("cadence", 0) == 1 and any(f"field {fid}:" in p for p in broken.problems)


def test_executed_state_reads_done_half_done_failed_and_too_close_exposures(skymap_220722v):
    from astropy.time import Time

    from mushrooms.scheduler_core.replan import executed_state

    grid = load_ztf_fields()
    fp = field_footprints(grid, CFG.nside)
    t0 = Time("2022-07-23T05:00:00", scale="utc")

    def e(fid, filt, minutes, fraction=1.0, status="processed"):
        return ExecutedExposure(fid, filt, t0 + TimeDelta(minutes * 60.0, format="sec"), 300.0, fraction, status)

    record = [e(862, "g", 0), e(862, "r", 40),                 # done in both, 40 min apart
              e(843, "g", 0), e(843, "r", 10),                 # both, too close: still needs r a cadence after g
              e(864, "r", 5), e(864, "g", 50, 0.0, "failed"),  # g failed: needs g
              e(1850, "g", 0), e(1850, "r", 40, 0.3),          # r only partly reduced: needs r
              e(861, "i", 0)]                                  # a third filter: nothing
    start = t0 + TimeDelta(3600.0, format="sec")
    state = executed_state(skymap_220722v, CFG, start, record, fp, grid)
    assert state.covered.tolist() == [862]
    pending = {v.field_id: (v.filter, v.due_s) for v in state.pending}
    assert pending == {843: ("r", 0.0), 864: ("g", 0.0), 1850: ("r", 0.0)}
    assert state.uncovered[fp.pixels(862)].sum() == 0 and state.uncovered[fp.pixels(861)].sum() > 0
    assert state.coverage_executed == pytest.approx(fp.coverage([862], skymap_220722v.prob))
    # a start 10 min after the first exposure: the other filter falls due 20 min later
    soon = executed_state(skymap_220722v, CFG, t0 + TimeDelta(600.0, format="sec"), record, fp, grid)
    assert {v.field_id: v.due_s for v in soon.pending}[843] == pytest.approx(CFG.cadence_s - 600.0)


def test_a_replan_describes_the_same_localization_as_the_plan_it_supersedes(first_plan, skymap_220722v):
    # the re-plan plans on the probability still to cover, but its event block (areas, distance) is the map's
    executed = executed_from(first_plan, 20)
    start = executed[-1].end + TimeDelta(10 * 60, format="sec")
    replan = plan_remaining(skymap_220722v, CFG, start, executed, event=first_plan.event)
    fresh = plan_remaining(skymap_220722v, CFG, start, executed)
    assert replan.metrics.coverage_executed > 0.02  # a real share of the map is done and left out of the planning
    for plan in (replan, fresh):
        for key in ("area_50_deg2", "area_90_deg2", "distance_mpc", "distance_std_mpc"):
            assert getattr(plan.event, key) == getattr(first_plan.event, key), key
