"""The daemon's path publishes a not_observable answer, not a useless plan."""

from __future__ import annotations

import dataclasses
import json
from datetime import timedelta

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import DirectorySink
from mushrooms.daemon.state.store import Store
from mushrooms.scheduler_core.plan.schema import validate_document

from replay_helpers import FAST, created, raw


def test_an_event_next_to_the_sun_is_answered_not_observable_then_withdrawn(tmp_path):
    # the shared FAST config turns the thresholds off; here they are the defaults
    config = dataclasses.replace(FAST, scheduler=dataclasses.replace(FAST.scheduler, min_gain=0.001,
                                                                     min_coverage=0.01))
    store = Store(tmp_path / "state.sqlite")
    try:
        p = NoticePipeline.from_config(config, store, DirectorySink(tmp_path / "out"))
        rel = "json/MS181101ab-preliminary.json"
        oc = p.handle(raw(rel), f"test:{rel}", created(rel) + timedelta(minutes=0.5))
        assert oc.decision == "plan" and oc.published and oc.reason.startswith("not observable")
        doc = json.loads((tmp_path / "out" / f"{oc.plan_id}.json").read_text())
        validate_document(doc)
        assert doc["type"] == "not_observable" and doc["event"]["superevent_id"] == "MS181101ab"
        assert doc["sky"]["daylight"] > 0.9 and "Sun" in doc["reasons"][0]
        rel = "json/MS181101ab-retraction.json"
        gone = p.handle(raw(rel), f"test:{rel}", created(rel) + timedelta(minutes=0.5))
        assert gone.decision == "withdraw" and oc.plan_id in gone.plan_ids
        for path in (tmp_path / "out").glob("withdrawal-*.json"):
            validate_document(json.loads(path.read_text()))
    finally:
        store.close()
