"""ZTF queue and SkyPortal exports, checked against the keys and types SkyPortal's handlers read,
and the JSON Schema of the plan document.

The expected keys and types are those of SkyPortal (skyportal/skyportal):
``facility_apis/ztf.py`` (``_build_observation_plan_payload`` and ``ZTFMMAAPI.send``:
the body of ``PUT api/triggers/ztf``) and ``handlers/api/observation_plan.py``
(``ObservationPlanManualRequestHandler.post``; ``PlannedObservation`` stores
``exposure_time`` and ``overhead_per_exposure`` as integers).
"""

from __future__ import annotations

import dataclasses
import json

import jsonschema
import pytest
from astropy.time import Time

from mushrooms.scheduler_core import ExportConfig, Plan, to_skyportal, to_trigger_queue
from mushrooms.scheduler_core.plan.schema import document_schema, validate_document

QUEUE_TOP = {"queue_name": str, "queue_type": str, "validity_window_mjd": list, "user": str, "targets": list}
QUEUE_TARGET = {"request_id": int, "program_id": int, "field_id": int, "ra": float, "dec": float,
                "filter_id": int, "exposure_time": float, "program_pi": str, "subprogram_name": str}
SKYPORTAL_TOP = {"dateobs": str, "localization_name": str, "allocation_id": int, "plan_name": str,
                 "status": str, "payload": dict, "observation_plans": list}
SKYPORTAL_PLAN = {"validity_window_start": str, "validity_window_end": str, "status": str,
                  "planned_observations": list}
SKYPORTAL_OBS = {"planned_observation_id": int, "dateobs": str, "field_id": int, "exposure_time": int,
                 "filt": str, "weight": float, "overhead_per_exposure": int, "limiting_mag": float}
EXPORT = ExportConfig(program="Caltech", program_pi="Kasliwal", subprogram_name="GWtest", user="alice",
                      skyportal_allocation_id=7)


def _typed(obj, spec):
    assert set(obj) == set(spec), set(obj) ^ set(spec)
    for key, kind in spec.items():
        assert type(obj[key]) is kind, (key, obj[key])


def test_queue_has_every_field_skyportal_sends_with_program_fields_from_config(greedy_plan):
    q = to_trigger_queue(greedy_plan, EXPORT)
    _typed(q, QUEUE_TOP)
    assert q["queue_type"] == "list" and q["user"] == "alice" and q["queue_name"].startswith("ToO_")
    assert q["validity_window_mjd"] == [greedy_plan.start.mjd, greedy_plan.end.mjd]
    assert len(q["targets"]) == len(greedy_plan.observations)
    for i, (t, o) in enumerate(zip(q["targets"], greedy_plan.observations)):
        _typed(t, QUEUE_TARGET)
        assert t["request_id"] == i + 1 and t["field_id"] == o.field_id
        assert t["filter_id"] == {"g": 1, "r": 2, "i": 3}[o.filter]
        assert t["program_id"] == 3 and t["program_pi"] == "Kasliwal/alice" and t["subprogram_name"] == "ToO_GWtest"
    json.dumps(q)


def test_empty_plan_and_foreign_filter_have_no_queue(greedy_plan):
    with pytest.raises(ValueError, match="no observations"):
        to_trigger_queue(greedy_plan.with_(observations=()))
    odd = tuple(dataclasses.replace(o, filter="x") for o in greedy_plan.observations)
    with pytest.raises(ValueError, match="not ZTF filters"):
        to_trigger_queue(greedy_plan.with_(observations=odd))


def test_skyportal_manual_plan_payload_has_the_keys_and_types_the_handler_reads(greedy_plan):
    body = to_skyportal(greedy_plan, EXPORT)
    _typed(body, SKYPORTAL_TOP)
    assert body["allocation_id"] == 7 and body["localization_name"] == "MS220722v_bayestar.multiorder.fits"
    Time(body["dateobs"], format="isot")  # the handler finds the GcnEvent by this dateobs
    assert body["dateobs"].startswith(greedy_plan.event.event_time[:19])
    (plan,) = body["observation_plans"]
    _typed(plan, SKYPORTAL_PLAN)
    assert len(plan["planned_observations"]) == len(greedy_plan.observations)
    for i, (p, o) in enumerate(zip(plan["planned_observations"], greedy_plan.observations)):
        _typed(p, SKYPORTAL_OBS)
        assert p["planned_observation_id"] == i and p["filt"] == {"g": "ztfg", "r": "ztfr"}[o.filter]
        assert p["exposure_time"] == 300 and 0 < p["weight"] <= 1 and 0 <= p["overhead_per_exposure"] <= 600
        assert abs((Time(p["dateobs"], format="isot") - greedy_plan.absolute_time(o.start)).to_value("s")) < 1e-2
        assert p["limiting_mag"] == round(o.limiting_mag, 2)  # ours: the handler reads its own keys by name
    # what SkyPortal's ZTF API reads back from the request payload to queue the plan
    pay = body["payload"]
    assert pay["program_id"] == "Caltech" and pay["subprogram_name"] == "GWtest" and pay["queue_name"]
    assert Time(pay["start_date"], format="iso").mjd == pytest.approx(greedy_plan.start.mjd, abs=1e-4)
    assert Time(pay["end_date"], format="iso").mjd == pytest.approx(greedy_plan.end.mjd, abs=1e-4)


def test_skyportal_needs_an_allocation_an_event_time_and_observations(greedy_plan):
    with pytest.raises(ValueError, match="skyportal_allocation_id"):
        to_skyportal(greedy_plan, ExportConfig())
    with pytest.raises(ValueError, match="no observations"):
        to_skyportal(greedy_plan.with_(observations=()), EXPORT)
    no_time = greedy_plan.with_(event=dataclasses.replace(greedy_plan.event, event_time=None))
    with pytest.raises(ValueError, match="event time"):
        to_skyportal(no_time, EXPORT)


def test_export_config_is_checked():
    with pytest.raises(ValueError, match="Partnership or Caltech"):
        ExportConfig(program="MSIP")
    with pytest.raises(ValueError, match="user must not be empty"):
        ExportConfig(user=" ")


def test_plan_document_carries_end_airmass_probability_event_time_and_config(greedy_plan, greedy_config):
    doc = greedy_plan.to_document()
    validate_document(doc)
    for o in doc["observations"]:
        assert (Time(o["end"][:-1]) - Time(o["start"][:-1])).to_value("s") == pytest.approx(o["exposure_s"], abs=2e-3)
        assert 1.0 <= o["airmass"] <= greedy_config.airmass_max + 0.01 and 0 < o["probability"] <= 1
    assert doc["event"]["event_time"] and doc["event"]["skymap_name"].endswith(".fits")
    assert doc["config"]["solver"] == "greedy" and doc["config"]["filters"] == ["g", "r"]
    back = Plan.from_document(json.loads(json.dumps(doc)))
    assert back.config == doc["config"] and back.observations[0].airmass == doc["observations"][0]["airmass"]


def test_schema_refuses_what_a_reader_could_not_use(greedy_plan):
    doc = greedy_plan.to_document()
    bad_filter = json.loads(json.dumps(doc))
    bad_filter["observations"][0]["filter"] = "x"
    no_metrics = {k: v for k, v in doc.items() if k != "metrics"}
    typo = dict(doc, covrage=0.5)
    for bad in (bad_filter, no_metrics, typo, {"type": "plan"}, {"type": "advice"}):
        with pytest.raises(jsonschema.ValidationError):
            validate_document(bad)


def test_schema_allows_the_fields_other_parts_add(greedy_plan):
    doc = json.loads(json.dumps(greedy_plan.to_document()))
    doc.update(revision=2, final=False)
    doc["metrics"].update(upper_bound=0.5, expected_detections={"kilonova": 0.3})
    validate_document(doc)
    withdrawal = {"type": "withdrawal", "withdrawal_id": "withdrawal-S1-abc", "superevent_id": "S1",
                  "plan_ids": [greedy_plan.plan_id], "reason": "retracted", "created": "2026-01-01T00:00:00.000Z",
                  "revision": 3, "final": True}
    validate_document(withdrawal)
    assert set(document_schema()["$defs"]) >= {"plan", "not_observable", "withdrawal"}
