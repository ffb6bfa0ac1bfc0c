"""The alert shapes of the next observing run, through the daemon's own path (parse -> policy -> decide -> store).

Each shape is a real archived notice with a few fields edited (``tests/data/notices/shapes/``, built by
``benchmarks/attacks/make_alert_shapes.py``; SOURCES.md lists the edits).  Every test asserts the decision,
its reason in the store, and the one log line that says it: no shape is dropped silently, and each is
decided by a ``[policy]`` key that the reason names.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.handlers.policy import PolicyConfig

from replay_helpers import FAST, NOTICES

SHAPES = NOTICES / "shapes"
MERGER = datetime(2018, 11, 1, 22, 22, 46, 654000, tzinfo=timezone.utc)  # event.time of every MS181101ab notice


def shape(name: str) -> bytes:
    return (SHAPES / name).read_bytes()


def edited(name: str, **event_changes) -> bytes:
    d = json.loads(shape(name))
    for k, v in event_changes.items():
        if v is ...:
            d["event"].pop(k, None)
        else:
            d["event"][k] = v
    return json.dumps(d).encode()


def run(store, data: bytes, received_at: datetime, caplog, sink=None, **policy):
    """One notice through NoticePipeline.handle; the outcome and the pipeline's decision log line."""
    cfg = dataclasses.replace(FAST, policy=PolicyConfig(allow_mock=True, **policy))
    p = NoticePipeline.from_config(cfg, store, sink if sink is not None else MemorySink())
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="mushrooms.daemon.pipeline"):
        out = p.handle(data, "test:shape", received_at)
    lines = [r for r in caplog.records if r.name == "mushrooms.daemon.pipeline"
             and r.getMessage().startswith("notice ") and " decision=" in r.getMessage()]
    assert len(lines) == 1, [r.getMessage() for r in lines]  # one line says what happened to it
    row = store.decisions()[-1]
    assert row["decision"] in (out.decision, "plan", "rerun") and row["reason"]
    return out, lines[0], row


def created(data: bytes) -> datetime:
    return datetime.fromisoformat(json.loads(data)["time_created"].replace("Z", "+00:00"))


# ---------------------------------------------------------------- sub-solar mass


@pytest.mark.parametrize("key", ["HasSSM", "has_SSM"])
def test_a_sub_solar_mass_alert_is_ignored_by_default_and_says_which_key(store, caplog, key):
    data = shape("MS181101ab-ssm-preliminary.json") if key == "HasSSM" else \
        edited("MS181101ab-ssm-preliminary.json", classification=..., properties={"HasNS": 1.0, "has_SSM": 0.98})
    out, line, row = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "ignore" and out.plan_id is None
    assert "sub-solar-mass" in out.reason and "plan_sub_solar_mass = false" in out.reason
    assert "HasNS" not in out.reason.split("sub-solar-mass")[0]  # not decided as a neutron star
    assert row["reason"] == out.reason and repr(out.reason) in line.getMessage()


def test_a_sub_solar_mass_alert_is_planned_when_the_policy_says_so(store, caplog):
    data = shape("MS181101ab-ssm-preliminary.json")
    out, line, _ = run(store, data, created(data) + timedelta(seconds=30), caplog, plan_sub_solar_mass=True)
    assert out.decision == "plan" and out.published
    acc = [r.getMessage() for r in caplog.records if "decision=plan reason=" in r.getMessage()][0]
    assert "sub-solar-mass" in acc and "plan_sub_solar_mass = true" in acc


def test_a_classified_bns_with_a_hasssm_property_is_still_decided_as_a_bns(store, caplog):
    data = edited("MS181101ab-unclassified-preliminary.json",
                  classification={"BNS": 0.95, "NSBH": 0.01, "BBH": 0.03, "Terrestrial": 0.01},
                  properties={"HasNS": 0.95, "HasSSM": 0.0})
    out, line, _ = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "plan"
    assert "P(BNS)+P(NSBH) 0.960" in line.getMessage() and "sub-solar" not in line.getMessage()


# ---------------------------------------------------------------- early warning before the merger


def test_an_early_warning_before_its_merger_is_planned_from_the_merger(store, caplog):
    """45.7 s before the merger, with clocks trusted to 10 s: planned, the horizon from the merger."""
    data = shape("MS181101ab-earlywarning-premerger.json")
    received = created(data) + timedelta(seconds=2)  # 43.654 s before the merger
    out, line, _ = run(store, data, received, caplog, max_clock_skew_s=10.0)
    msg = line.getMessage()
    assert out.decision == "plan", out.reason
    assert "early warning" in msg and "merger 44 s after receipt" in msg
    assert "start=2018-11-01T22:22:46.654Z" in msg  # the plan's horizon starts at the merger, not before


def test_an_early_warning_planned_from_its_creation_still_starts_at_the_merger(store, caplog):
    data = shape("MS181101ab-earlywarning-premerger.json")
    out, line, _ = run(store, data, created(data) + timedelta(seconds=2), caplog, plan_start="created")
    assert out.decision == "plan"
    assert "start=2018-11-01T22:22:46.654Z" in line.getMessage()  # not 22:22:01, before the merger


def test_an_early_warning_too_far_ahead_of_its_merger_is_rejected_naming_the_key(store, caplog):
    d = json.loads(shape("MS181101ab-earlywarning-premerger.json"))
    d["time_created"] = "2018-11-01T21:50:00Z"  # 1967 s before the merger
    data = json.dumps(d).encode()
    out, line, _ = run(store, data, created(data) + timedelta(seconds=2), caplog, max_clock_skew_s=10.0)
    assert out.decision == "rejected"
    assert "max_early_warning_lead_s" in out.reason and line.levelno == logging.WARNING


def test_a_preliminary_dated_before_its_merger_is_still_a_clock_error(store, caplog):
    d = json.loads(shape("MS181101ab-earlywarning-premerger.json"))
    d["alert_type"] = "PRELIMINARY"
    data = json.dumps(d).encode()
    out, _, _ = run(store, data, created(data) + timedelta(seconds=2), caplog, max_clock_skew_s=10.0)
    assert out.decision == "rejected" and "in the future" in out.reason


# ---------------------------------------------------------------- schema 1.3.0


def test_a_schema_130_notice_with_mchirp_source_and_a_string_notice_id_is_planned(store, caplog):
    sink = MemorySink()
    data = shape("MS181101ab-schema130-update.json")
    out, line, _ = run(store, data, created(data) + timedelta(seconds=30), caplog, sink=sink)
    assert out.decision == "plan", out.reason
    acc = [r.getMessage() for r in caplog.records if "decision=plan reason=" in r.getMessage()][0]
    assert "chirp mass 1.05-1.2 Msun (p 0.70)" in acc and "combined map" in acc
    ext = sink.messages[0]["event"]["external_coinc"]
    assert ext["gcn_notice_id"] == "524666471" and ext["observatory"] == "Fermi"


def test_a_malformed_mchirp_source_is_noted_not_fatal(store, caplog):
    data = edited("MS181101ab-schema130-update.json", mchirp_source={"bin_edges": [1.0, 1.2], "probabilities": [0.5, 0.5]})
    out, _, _ = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "plan", out.reason
    acc = [r.getMessage() for r in caplog.records if "decision=plan reason=" in r.getMessage()][0]
    assert "mchirp_source not used" in acc and "2 bin edges for 2 probabilities" in acc


# ---------------------------------------------------------------- no classification


def test_a_notice_without_classification_is_ignored_by_default_and_says_so(store, caplog):
    data = shape("MS181101ab-unclassified-preliminary.json")
    out, line, row = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "ignore"
    assert "no source classification" in out.reason and "plan_unclassified = false" in out.reason
    assert line.levelno == logging.WARNING  # a CBC candidate nobody could classify: the operator should see it
    assert row["reason"] == out.reason


def test_a_notice_without_classification_is_planned_when_the_policy_says_so(store, caplog):
    data = shape("MS181101ab-unclassified-preliminary.json")
    out, _, _ = run(store, data, created(data) + timedelta(seconds=30), caplog, plan_unclassified=True)
    assert out.decision == "plan" and out.published


def test_a_notice_without_classification_but_with_hasns_is_decided_by_hasns(store, caplog):
    data = edited("MS181101ab-unclassified-preliminary.json", properties={"HasNS": 0.95})
    out, line, _ = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "plan"
    assert "no source classification in the notice; HasNS 0.950 >= 0.5" in line.getMessage()


# ---------------------------------------------------------------- significant = false


def test_a_low_significance_alert_is_ignored_naming_require_significant(store, caplog):
    data = shape("MS181101ab-lowsignificance-preliminary.json")
    out, line, _ = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "ignore"
    assert "significant = false" in out.reason and "require_significant = true" in out.reason


def test_a_low_significance_alert_is_planned_when_the_policy_accepts_them(store, caplog):
    data = shape("MS181101ab-lowsignificance-preliminary.json")
    out, _, _ = run(store, data, created(data) + timedelta(seconds=30), caplog,
                    require_significant=False, max_far_hz=1e-5)
    assert out.decision == "plan"
    acc = [r.getMessage() for r in caplog.records if "decision=plan reason=" in r.getMessage()][0]
    assert "low-significance alert accepted (require_significant = false)" in acc


# ---------------------------------------------------------------- no sky map


def test_a_notice_with_a_null_sky_map_is_ignored_with_a_reason_not_rejected(store, caplog):
    data = shape("MS181101ab-nomap-preliminary.json")
    out, line, _ = run(store, data, created(data) + timedelta(seconds=30), caplog)
    assert out.decision == "ignore"
    assert "no sky map" in out.reason and line.levelno == logging.WARNING


def test_every_shape_file_is_tested_here():
    names = sorted(p.name for p in Path(SHAPES).iterdir())
    text = Path(__file__).read_text()
    assert names and all(n in text for n in names)
