"""A g-r-g plan through the queue export and the executor model, and a re-plan of half-done g-r-g fields (F1, F3).

Real map (MS220722v), real greedy, the real telescope model; the credit
cases of the executor's coverage are worked by hand.
"""

from __future__ import annotations

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan
from mushrooms.scheduler_core.executed import ExecutedExposure
from mushrooms.scheduler_core.plan.exports import FILTER_IDS, to_trigger_queues
from mushrooms.scheduler_core.replan import plan_remaining
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues, queue_coverage

GRG = PlanningConfig(solver="greedy", filters=("g", "r", "g"), exposure_s=180.0)


@pytest.fixture(scope="module")
def grg_plan(skymap_220722v):
    return make_plan(skymap_220722v, GRG)


@pytest.fixture(scope="module")
def footprints():
    return field_footprints(load_ztf_fields(), GRG.nside)


def by_field(exposures):
    out: dict[int, list] = {}
    for e in exposures:
        out.setdefault(e.field_id, []).append(e)
    return {f: sorted(v, key=lambda e: e.start.unix) for f, v in out.items()}


def test_one_queue_per_filter_pass_g_r_g(grg_plan):
    queues = to_trigger_queues(grg_plan)
    filters = [{t["filter_id"] for t in q["targets"]} for q in queues]
    assert all(len(f) == 1 for f in filters)
    ids = [f.pop() for f in filters]
    assert ids[:3] == [FILTER_IDS["g"], FILTER_IDS["r"], FILTER_IDS["g"]]
    assert all(a != b for a, b in zip(ids, ids[1:]))  # consecutive passes change filter
    # every planned exposure is in exactly one queue, once
    sent = sorted((t["field_id"], t["filter_id"]) for q in queues for t in q["targets"])
    assert sent == sorted((o.field_id, FILTER_IDS[o.filter]) for o in grg_plan.observations)


def test_the_executor_runs_each_field_in_sequence_and_credits_the_first_two_visits(grg_plan, skymap_220722v,
                                                                                footprints):
    executed = execute_plan_queues(grg_plan)
    runs = by_field(executed)
    assert runs
    credited = []
    for fid, visits in runs.items():
        bands = [e.filter for e in visits]
        assert bands == ["g", "r", "g"][:len(bands)]  # the passes' queues keep the sequence's order
        # (F1) a g and an r visit a cadence apart, either order: g-r too close is saved by r-g
        g = [e.start.unix for e in visits if e.filter == "g"]
        r = [e.start.unix for e in visits if e.filter == "r"]
        if any(abs(a - b) >= GRG.cadence_s for a in g for b in r):
            credited.append(fid)
    assert len(credited) >= len(runs) // 2
    as_executed = queue_coverage(grg_plan, footprints, skymap_220722v.prob)
    assert as_executed == pytest.approx(footprints.coverage(credited, skymap_220722v.prob), abs=1e-9)
    assert as_executed == pytest.approx(grg_plan.metrics.coverage_as_executed, abs=1e-6)
    assert 0 < as_executed <= grg_plan.metrics.coverage + 1e-6  # metrics hold 6 decimals


def _minutes(field_id, *visits):
    t0 = Time("2026-05-01T04:00:00", scale="utc")
    return [ExecutedExposure(field_id, f, t0 + TimeDelta(m * 60, format="sec"), 180.0, 1.0, "processed")
            for f, m in visits]


def test_the_executors_credit_counts_the_first_two_visits(footprints):
    prob = np.zeros(12 * GRG.nside ** 2)
    prob[footprints.pixels(700)] = 1.0
    prob[footprints.pixels(701)] = 1.0
    prob /= prob.sum()
    share = footprints.coverage([700], prob)
    grg = ("g", "r", "g")
    # g and r 35 min apart: covered, the third visit missing; g, r, g at 0, 20, 45 min: no g and r 30 min
    # apart, not covered; at 0, 20, 55 min: the r and the last g are 35 min apart, covered
    assert cadence_coverage(_minutes(700, ("g", 0), ("r", 35)), footprints, prob, grg, 1800.0) == pytest.approx(share)
    assert cadence_coverage(_minutes(700, ("g", 0), ("r", 20), ("g", 45)), footprints, prob, grg, 1800.0) == 0.0
    assert cadence_coverage(_minutes(700, ("g", 0), ("r", 20), ("g", 55)), footprints, prob, grg,
                            1800.0) == pytest.approx(share)
    assert cadence_coverage(_minutes(700, ("g", 0)), footprints, prob, ("g",), 1800.0) == pytest.approx(share)


def test_a_replan_keeps_the_third_visit_of_fields_done_in_g_and_r(grg_plan, skymap_220722v, footprints):
    # the telescope did the g and r visits of the first block's fields, nothing else
    block0 = [o for o in grg_plan.observations if o.block == 0]
    half = [o for o in block0 if not (o.filter == "g" and o.start > min(x.start for x in block0 if x.filter == "r"))]
    fields = sorted({o.field_id for o in half})
    planned = [o.field_id for o in block0]
    whole = [f for f in fields if planned.count(f) == 3]  # not those F10 cut: no window holds a third visit
    executed = [ExecutedExposure(o.field_id, o.filter, grg_plan.absolute_time(o.start), o.exposure_s, 1.0, "processed")
                for o in half]
    start = max(e.end for e in executed)
    replan = plan_remaining(skymap_220722v, GRG, start, executed)
    assert check_plan(replan, skymap_220722v, GRG, executed=executed).ok
    r_done = {e.field_id: e.start for e in executed if e.filter == "r"}
    kept = 0
    for fid in fields:
        mine = [o for o in replan.observations if o.field_id == fid]
        assert len(mine) <= 1 and all(o.filter == "g" for o in mine)  # the third visit, nothing else of them
        for o in mine:
            assert float((replan.absolute_time(o.start) - r_done[fid]).to_value("s")) >= GRG.cadence_s - 1e-6
            kept += 1
    assert kept >= len(whole) - 1
    assert replan.metrics.coverage_executed == pytest.approx(footprints.coverage(fields, skymap_220722v.prob), abs=1e-6)
    # the third visits add no coverage: the re-plan's coverage is its other fields' only
    others = {o.field_id for o in replan.observations} - set(fields)
    assert replan.metrics.coverage == pytest.approx(
        footprints.coverage(sorted(others | set(fields)), skymap_220722v.prob)
        - footprints.coverage(fields, skymap_220722v.prob), abs=2e-3)
