"""A plan's queue set (one timed queue per filter pass) and its ``coverage_as_executed`` (Q11-Q14)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
from mushrooms.scheduler_core.plan.document import Plan
from mushrooms.scheduler_core.plan.exports import ExportConfig, filter_passes, to_trigger_queue, to_trigger_queues
from mushrooms.scheduler_core.plan.schema import validate_document
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.telescope import TelescopeTiming
from mushrooms.scheduler_core.schedulers.as_executed import execute_plan_queues, queue_coverage

MAP = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


@pytest.fixture(scope="module", params=[0.0, 1.0], ids=["night1", "night2"])
def planned(request):
    cfg = PlanningConfig(solver="greedy", nside=64)
    skymap = read_skymap(MAP, nside=cfg.nside)
    plan = make_plan(skymap, cfg, Time(skymap.event_time, scale="utc") + TimeDelta(request.param, format="jd"))
    assert plan.observations
    return cfg, skymap, plan, field_footprints(load_ztf_fields(), cfg.nside)


def test_one_named_timed_queue_per_filter_pass_in_plan_order(planned):
    _, _, plan, _ = planned
    queues = to_trigger_queues(plan, ExportConfig(), name_base="ToO_GW_S1_r2")
    passes = filter_passes(plan)
    assert 1 < len(queues) <= len(passes)
    assert [q["queue_name"] for q in queues] == [f"ToO_GW_S1_r2_{k}" for k in range(1, len(queues) + 1)]
    single = to_trigger_queue(plan)
    keys = [(t["field_id"], t["filter_id"]) for q in queues for t in q["targets"]]
    assert keys == [(t["field_id"], t["filter_id"]) for t in single["targets"]][:len(keys)]  # plan order
    by_key = {(o.field_id, {"g": 1, "r": 2, "i": 3}[o.filter]): o for o in plan.observations}
    for q in queues:
        assert set(q) == set(single)
        assert [t["request_id"] for t in q["targets"]] == list(range(1, len(q["targets"]) + 1))
        assert len({by_key[t["field_id"], t["filter_id"]].filter for t in q["targets"]}) == 1
        lo, hi = q["validity_window_mjd"]
        first = min(by_key[t["field_id"], t["filter_id"]].start for t in q["targets"])
        assert plan.absolute_time(first).mjd - 1e-8 <= lo < hi <= plan.end.mjd + 1e-8  # never before the plan


def test_coverage_as_executed_is_what_the_submitted_queues_give(planned):
    cfg, skymap, plan, footprints = planned
    m = plan.metrics
    assert m.coverage_as_executed is not None and 0 < m.coverage_as_executed <= m.coverage + 1e-9
    # the queues as written to a file (JSON) and read back by the executor: the same number
    sent = json.loads(json.dumps(to_trigger_queues(plan)))
    assert queue_coverage(plan, footprints, skymap.prob, queues=sent) == pytest.approx(m.coverage_as_executed,
                                                                                     abs=1e-6)
    # the old single list queue keeps less at the cadence
    old = queue_coverage(plan, footprints, skymap.prob, queues=[to_trigger_queue(plan)])
    assert old <= m.coverage_as_executed + 1e-9
    # the document carries it and the schema knows it
    doc = plan.to_document()
    assert doc["metrics"]["coverage_as_executed"] == m.coverage_as_executed
    validate_document(doc)
    assert Plan.from_document(doc).metrics.coverage_as_executed == m.coverage_as_executed


@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_a_telescope_a_little_faster_or_slower_keeps_the_pairs(planned, factor):
    cfg, skymap, plan, footprints = planned
    got = queue_coverage(plan, footprints, skymap.prob, timing=TelescopeTiming().scaled(factor))
    assert got >= 0.95 * plan.metrics.coverage_as_executed


def test_a_late_start_loses_time_not_the_queues(planned):
    cfg, skymap, plan, footprints = planned
    late = execute_plan_queues(plan, late_s=900.0)
    first = plan.absolute_time(plan.observations[0].start + 900.0)
    assert all(e.start >= first for e in late)
    assert queue_coverage(plan, footprints, skymap.prob, late_s=900.0) <= plan.metrics.coverage_as_executed + 1e-9
