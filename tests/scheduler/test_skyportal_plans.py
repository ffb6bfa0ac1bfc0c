"""The SkyPortal target's plans: one observation plan per filter pass, queued by SkyPortal as the Kowalski set (T1).

Real plans (greedy, the MS220722v BAYESTAR map, two nights), the real queue
set of ``to_trigger_queues`` and the telescope's executor model.  What
SkyPortal's ZTF API makes of a plan (one list queue over the plan's
``start_date``..``end_date``) is :func:`mushrooms.evaluation.skyportal_queue.skyportal_queue`,
written from SkyPortal's source.
"""

from __future__ import annotations

import json

import pytest
from astropy.time import Time

from mushrooms.evaluation.skyportal_queue import skyportal_queue
from mushrooms.scheduler_core.plan.exports import (ExportConfig, to_skyportal, to_skyportal_plans, to_trigger_queue,
                                                   to_trigger_queues)
from mushrooms.scheduler_core.schedulers.as_executed import queue_coverage
from test_queue_export import planned  # noqa: F401 (the fixture: greedy plans of MS220722v, nights 1 and 2)

EXPORT = ExportConfig(skyportal_allocation_id=7)


def test_one_skyportal_plan_per_queue_of_the_set_with_its_window_and_targets(planned):
    _, _, plan, _ = planned
    queues = to_trigger_queues(plan, EXPORT, name_base="ToO_GW_S1_r2")
    bodies = json.loads(json.dumps(to_skyportal_plans(plan, EXPORT, name_base="GW_S1_r2")))  # as POSTed
    assert len(bodies) == len(queues) > 1
    assert [b["plan_name"] for b in bodies] == [f"GW_S1_r2_{k}" for k in range(1, len(queues) + 1)]
    whole = to_skyportal(plan, EXPORT)["observation_plans"][0]["planned_observations"]
    for body, queue in zip(bodies, queues):
        sent = skyportal_queue(body)
        assert sent["queue_name"] == queue["queue_name"]
        assert sent["validity_window_mjd"] == pytest.approx(queue["validity_window_mjd"], abs=2e-3 / 86400)
        assert [(t["field_id"], t["filter_id"]) for t in sent["targets"]] == [
            (t["field_id"], t["filter_id"]) for t in queue["targets"]]
        (one,) = body["observation_plans"]
        assert (one["validity_window_start"], one["validity_window_end"]) == tuple(
            Time(body["payload"][k], format="iso").isot[:23] for k in ("start_date", "end_date"))
        assert all(o == whole[o["planned_observation_id"]] for o in one["planned_observations"])
        assert body["payload"]["filters"] == {o["filt"][-1] for o in one["planned_observations"]}.pop()
        assert {k: body[k] for k in ("dateobs", "localization_name", "allocation_id")} == {
            k: bodies[0][k] for k in ("dateobs", "localization_name", "allocation_id")}


def test_the_per_pass_plans_are_executed_as_coverage_as_executed_says(planned):
    _, skymap, plan, footprints = planned
    sent = [skyportal_queue(b) for b in to_skyportal_plans(plan, EXPORT)]
    got = queue_coverage(plan, footprints, skymap.prob, queues=sent)
    assert got == pytest.approx(plan.metrics.coverage_as_executed, abs=1e-6)
    # one plan over the whole window (the switch back) is one list queue: what the old export keeps
    (single,) = to_skyportal_plans(plan, ExportConfig(skyportal_allocation_id=7, skyportal_plans="single"))
    old = queue_coverage(plan, footprints, skymap.prob, queues=[skyportal_queue(single)])
    assert old == pytest.approx(queue_coverage(plan, footprints, skymap.prob, queues=[to_trigger_queue(plan)]),
                                abs=1e-6)
    assert old <= got + 1e-9


def test_the_single_plan_switch_gives_one_plan_over_the_plans_window(planned):
    _, _, plan, _ = planned
    (body,) = to_skyportal_plans(plan, ExportConfig(skyportal_allocation_id=7, skyportal_plans="single"), "GW_S1_r1")
    assert body["plan_name"] == body["payload"]["queue_name"] == "GW_S1_r1"
    assert len(body["observation_plans"][0]["planned_observations"]) == len(plan.observations)
    assert body["payload"]["start_date"] == plan.start.utc.iso[:19]


def test_an_unknown_skyportal_plans_value_is_refused_in_one_line():
    with pytest.raises(ValueError, match="skyportal_plans must be per_pass or single, got 'per_block'"):
        ExportConfig(skyportal_plans="per_block")


def test_plans_from_the_queue_set_already_timed_are_those_timed_again(planned):
    from mushrooms.scheduler_core.plan.exports import timed_passes

    _, _, plan, _ = planned
    passes = timed_passes(plan, EXPORT, "ToO_GW_S1_r2")
    assert passes.queues == to_trigger_queues(plan, EXPORT, name_base="ToO_GW_S1_r2")
    again = to_skyportal_plans(plan, EXPORT, name_base="GW_S1_r2")
    assert to_skyportal_plans(plan, EXPORT, name_base="GW_S1_r2", passes=passes) == again
    # a set timed under another name is not taken for this one
    other = timed_passes(plan, EXPORT, "ToO_other_r1")
    assert to_skyportal_plans(plan, EXPORT, name_base="GW_S1_r2", passes=other) == again
