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
    assert all(set(o) == set(OBSERVATION_KEYS) | {"end", "airmass", "probability", "probability_share", "coverage_after",
                                                  "limiting_mag"}
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


def test_every_exposure_carries_the_depth_the_detection_score_uses(greedy_plan):
    """limiting_mag is the difference-image depth (D2) at mid-exposure, the same number the reach (X2) is made of."""
    import numpy as np

    from mushrooms.report.summary import summary_text
    from mushrooms.scheduler_core.source.depth import sky_conditions, science_depth
    from mushrooms.scheduler_core.source.detection import exposure_depths

    obs = greedy_plan.observations
    depths = np.array([o.limiting_mag for o in obs])
    assert np.allclose(depths, exposure_depths(obs, greedy_plan.start), atol=1e-9)
    assert np.all((depths > 18.0) & (depths < 23.0))
    # shallower than the science image alone (the reference and the PSF matching cost depth)
    mid = greedy_plan.absolute_time([o.start + o.exposure_s / 2 for o in obs])
    cond = sky_conditions(np.array([o.ra for o in obs]), np.array([o.dec for o in obs]), mid)
    sci = science_depth(np.array([o.filter for o in obs]), np.array([o.exposure_s for o in obs]), cond)
    assert np.all(depths < sci)
    back = Plan.from_document(json.loads(greedy_plan.to_json()))
    assert [o.limiting_mag for o in back.observations] == [round(float(m), 2) for m in depths]
    text = summary_text(greedy_plan.to_document())
    assert "Depth" in text and f"{depths[0]:.1f}" in text.split("own prob")[1]
