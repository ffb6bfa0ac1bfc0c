"""Revisits from a start inside a night (``replan.md`` N4, N5): that night's earlier exposures still count.

MS220722v planned for two nights with ``revisit = true`` (greedy, the real
checker); the first night's first exposures executed, then a re-plan from
a start in the middle of that night, and the checker of night 2 given the
earlier night's record (as ``mushrooms check planN MAP --executed`` does).
"""

from __future__ import annotations

import dataclasses

import pytest
from astropy.time import TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan
from mushrooms.scheduler_core.executed import ExecutedExposure, done_pairs
from mushrooms.scheduler_core.nights import as_planned, plan_nights

CFG = PlanningConfig(solver="greedy", nights=2, revisit=True)


@pytest.fixture(scope="module")
def nights(skymap_220722v):
    return plan_nights(skymap_220722v, CFG)


def _first(plan, n):
    obs = sorted(plan.observations, key=lambda o: o.start)[:n]
    return [ExecutedExposure(o.field_id, o.filter, plan.absolute_time(o.start), o.exposure_s, 1.0, "processed")
            for o in obs]


def test_a_mid_night_re_plan_with_revisit_repeats_no_pair_done_that_night(nights, skymap_220722v):
    night1 = nights[0]
    done = _first(night1, 12)
    pairs = done_pairs(done, CFG.filters, cadence_s=CFG.cadence_s)
    assert pairs.both  # the record completes pairs on night 1
    start = max(e.end for e in done) + TimeDelta(600.0, format="sec")
    again = plan_nights(skymap_220722v, CFG, start, done)
    tonight = again[0]
    assert tonight.observations
    assert not {o.field_id for o in tonight.observations} & set(pairs.both)
    assert check_plan(tonight, skymap_220722v, CFG, executed=done).ok


def test_the_checker_of_a_later_night_with_revisit_counts_that_night_only(nights, skymap_220722v):
    night1, night2 = nights
    record = as_planned(night1)
    assert {o.field_id for o in night2.observations} & {e.field_id for e in record}  # night 2 revisits
    report = check_plan(night2, skymap_220722v, CFG, executed=record)
    assert report.ok, report.problems
    # without revisit, the same record makes the revisited fields repeats
    strict = check_plan(night2, skymap_220722v, dataclasses.replace(CFG, revisit=False), executed=record)
    assert not strict.ok and "repeat" in {line.split(":")[0] for line in strict.problems}


def test_a_half_done_field_of_last_night_is_planned_as_a_new_pair_tonight(nights, skymap_220722v):
    """(P10) a pair belongs to one night: last night's lone g exposure is not paired with an r tonight."""
    from mushrooms.scheduler_core.replan import plan_remaining
    from mushrooms.scheduler_core.sky.twilight import night_windows

    night1 = nights[0]
    firsts = {}
    for o in sorted(night1.observations, key=lambda o: o.start):
        firsts.setdefault(o.field_id, o)
    half = [ExecutedExposure(o.field_id, o.filter, night1.absolute_time(o.start), o.exposure_s, 1.0, "processed")
            for o in list(firsts.values())[:8]]  # each field's first exposure only: one filter done
    cfg = dataclasses.replace(CFG, nights=1, revisit=False)
    (evening, morning), = night_windows(night1.end + TimeDelta(3600.0, format="sec"), cfg, 1)
    tonight = plan_remaining(skymap_220722v, dataclasses.replace(cfg, horizon_h=(morning - evening).to_value("h")),
                             evening, half)
    planned = {}
    for o in tonight.observations:
        planned.setdefault(o.field_id, set()).add(o.filter)
    again = [e.field_id for e in half if e.field_id in planned]
    assert again  # the map's best fields are planned again tonight
    assert all(planned[f] == set(CFG.filters) for f in again), {f: planned[f] for f in again}
    assert check_plan(tonight, skymap_220722v, cfg, executed=half).ok


def test_the_checker_refuses_a_pair_a_day_apart(nights, skymap_220722v):
    night1, night2 = nights
    o = sorted(night2.observations, key=lambda o: o.start)[0]
    other = next(f for f in CFG.filters if f != o.filter)
    before = ExecutedExposure(o.field_id, other, night2.absolute_time(o.start) - TimeDelta(86400.0, format="sec"),
                              o.exposure_s, 1.0, "processed")
    lone = night2.with_(observations=(o,))
    report = check_plan(lone, skymap_220722v, dataclasses.replace(CFG, revisit=False), executed=[before])
    assert "cadence" in {line.split(":")[0] for line in report.problems}, report.problems
