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
