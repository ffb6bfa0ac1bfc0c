"""The plan document and the ZTF trigger-queue export."""

from __future__ import annotations

import json

import pytest

from mushrooms.scheduler_core import Plan, to_trigger_queue
from mushrooms.scheduler_core.plan.document import EVENT_KEYS, METRIC_KEYS, OBSERVATION_KEYS, PLAN_KEYS


def test_document_has_exactly_the_documented_keys(greedy_plan):
    doc = json.loads(greedy_plan.to_json())
    assert set(doc) == set(PLAN_KEYS) | {"type", "config"} and doc["type"] == "plan"
    assert doc["telescope"] == "ZTF" and doc["supersedes"] is None
    assert set(doc["metrics"]) == set(METRIC_KEYS)
    assert all(set(o) == set(OBSERVATION_KEYS) | {"end", "airmass", "probability", "probability_share", "coverage_after"}
               for o in doc["observations"])
    assert all(o["start"].endswith("Z") for o in doc["observations"])
    starts = [o["start"] for o in doc["observations"]]
    assert starts == sorted(starts)
    assert set(doc["event"]) == set(EVENT_KEYS)


def test_document_round_trips(greedy_plan):
    back = Plan.from_document(json.loads(greedy_plan.to_json()))
    assert back.plan_id == greedy_plan.plan_id
    assert len(back.observations) == len(greedy_plan.observations)
    for a, b in zip(back.observations, greedy_plan.observations):
        assert a.field_id == b.field_id and a.filter == b.filter
        assert a.start == pytest.approx(b.start, abs=2e-3)  # ms precision in ISO strings


def test_from_document_names_the_missing_key(greedy_plan):
    doc = greedy_plan.to_document()
    del doc["observations"][0]["filter"]
    with pytest.raises(ValueError, match="observation 0 lacks key"):
        Plan.from_document(doc)
