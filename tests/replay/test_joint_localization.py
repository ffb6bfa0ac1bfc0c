"""The service's path on notices with an external coincidence: joint maps planned, fallbacks."""

from __future__ import annotations

import base64
import json
import logging
import sqlite3
from datetime import timedelta

import pytest

from mushrooms.tool.config import Config
from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import SCHEMA_VERSION, Store
from mushrooms.handlers.alert import parse_notice
from mushrooms.handlers.policy import PolicyConfig

from replay_helpers import FAST, created, raw

EXT = "json/MS181101ab-ext-update.json"
EXT_AVRO = "avro/MS181101ab-ext-update.avro"
JOINT_SHA = "1e087b1837bd"
GW_SHA = "db875e1b8cc8"


@pytest.fixture
def store(tmp_path):
    s = Store(tmp_path / "state.sqlite")
    yield s
    s.close()


def handle(p, rel, data=None, minutes=0.5):
    return p.handle(data if data is not None else raw(rel), f"test:{rel}", created(rel) + timedelta(minutes=minutes))


def corrupted_ext() -> bytes:
    d = json.loads(raw(EXT))
    joint = base64.b64decode(d["external_coinc"]["combined_skymap"])
    d["external_coinc"]["combined_skymap"] = base64.b64encode(joint[:30000]).decode()  # truncated FITS
    return json.dumps(d).encode()


@pytest.mark.parametrize("ext", [EXT, EXT_AVRO])
def test_the_coincidence_update_supersedes_onto_the_joint_map(store, ext):
    sink = MemorySink()
    p = NoticePipeline.from_config(FAST, store, sink)
    first = handle(p, "json/MS181101ab-preliminary.json")
    joint = handle(p, ext)
    later = handle(p, "json/MS181101ab-update.json", minutes=1)
    gone = handle(p, "json/MS181101ab-retraction.json")
    assert [first.decision, joint.decision, later.decision, gone.decision] == ["plan", "rerun", "duplicate",
                                                                               "withdraw"]
    docs = [m for m in sink.messages if m["type"] == "plan"]
    assert [d["plan_id"] for d in docs] == [first.plan_id, joint.plan_id]
    gw_doc, joint_doc = docs
    assert gw_doc["event"]["localization"] == "gw" and gw_doc["event"]["skymap_sha256"].startswith(GW_SHA)
    assert joint_doc["supersedes"] == first.plan_id
    assert joint_doc["event"]["localization"] == "combined"
    assert joint_doc["event"]["skymap_sha256"].startswith(JOINT_SHA)
    coinc = joint_doc["event"]["external_coinc"]
    alert = parse_notice(raw(ext))
    assert coinc["observatory"] == "Fermi" and coinc["search"] == "GRB"
    assert coinc["time_sky_position_coincidence_far_hz"] == alert.external_coinc.time_sky_position_coincidence_far
    assert coinc["time_difference_s"] == alert.external_coinc.time_difference
    assert later.plan_id == joint.plan_id  # the GW-only UPDATE leaves the joint plan standing
    assert gone.plan_ids == (first.plan_id, joint.plan_id)
    reasons = [d["reason"] for d in store.decisions()]
    assert "keeping the joint localisation" in reasons[2]
    assert store.event_state("MS181101ab").localization == "combined"


def test_a_corrupted_joint_map_falls_back_to_the_gw_map_with_one_logged_reason(store, caplog):
    sink = MemorySink()
    p = NoticePipeline.from_config(FAST, store, sink)
    with caplog.at_level(logging.WARNING, logger="mushrooms.daemon.pipeline"):
        out = handle(p, EXT, data=corrupted_ext())
    assert out.decision == "plan" and out.published
    [doc] = sink.messages
    assert doc["event"]["localization"] == "gw" and doc["event"]["skymap_sha256"].startswith(GW_SHA)
    assert doc["event"]["external_coinc"]["observatory"] == "Fermi"  # the coincidence is still reported
    warnings = [r.getMessage() for r in caplog.records if "combined sky map unusable" in r.getMessage()]
    assert len(warnings) == 1 and "MS181101ab" in warnings[0]
    # the decision is taken on the combined map's headers; the job decodes it, falls back and keeps why
    [incident] = [r for r in store.connection().execute("SELECT kind, detail FROM incidents")]
    assert incident[0] == "combined_map_unusable" and "combined sky map unusable" in incident[1]
    assert json.loads(incident[1])["superevent_id"] == "MS181101ab"
    assert [p["document"]["event"]["localization"] for p in store.plans("MS181101ab")] == ["gw"]
    # and the operator reads it under the event in `mushrooms status`
    from mushrooms.daemon.state.views import connect_readonly
    from mushrooms.tool.status import collect, render

    conn = connect_readonly(store.path)
    try:
        report = render(collect(conn, 20, 10.0, 24.0))
    finally:
        conn.close()
    event_block = report.split("MS181101ab", 1)[1]
    assert "combined_map_unusable (job 1" in event_block and "planned on the GW map" in event_block


def test_the_policy_can_plan_the_gw_map_only(store):
    cfg = Config(scheduler=FAST.scheduler, policy=PolicyConfig(allow_mock=True, use_combined_skymap=False))
    sink = MemorySink()
    out = NoticePipeline.from_config(cfg, store, sink).handle(raw(EXT), "test:ext", created(EXT) + timedelta(minutes=1))
    assert out.decision == "plan"
    assert sink.messages[0]["event"]["localization"] == "gw"
    assert sink.messages[0]["event"]["skymap_sha256"].startswith(GW_SHA)


def test_a_manual_rerun_plans_the_joint_map(store):
    sink = MemorySink()
    p = NoticePipeline.from_config(FAST, store, sink)
    handle(p, EXT)
    acc = p.rerun_superevent("MS181101ab", "trigger:test", created(EXT) + timedelta(minutes=2))
    assert acc.action == "rerun" and acc.job is not None
    assert acc.job.skymap_sha256.startswith(JOINT_SHA)
    out = p.run_job(acc.job)
    assert out.decision == "rerun"
    assert sink.messages[-1]["event"]["localization"] == "combined"


def test_a_state_file_of_schema_1_is_migrated_and_keeps_its_events(tmp_path):
    path = tmp_path / "old.sqlite"
    Store(path).close()
    conn = sqlite3.connect(path)  # turn it into a schema-1 file: no localization (2), submissions (3), latest_created (4)
    conn.executescript("ALTER TABLE events DROP COLUMN localization;"
                       "ALTER TABLE events DROP COLUMN latest_created;"  # schema 4
                       "DROP TABLE submissions;"  # schema 3
                       "INSERT INTO events(superevent_id, skymap_sha256, retracted, updated_at)"
                       " VALUES ('S1', 'abc', 0, '2026-01-01T00:00:00');"
                       "PRAGMA user_version=1;")
    conn.close()
    s = Store(path)
    try:
        st = s.event_state("S1")
        assert (st.skymap_sha256, st.retracted, st.localization) == ("abc", False, None)
    finally:
        s.close()
    conn = sqlite3.connect(path)
    assert conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    assert "localization" in [r[1] for r in conn.execute("PRAGMA table_info(events)")]
    conn.close()
