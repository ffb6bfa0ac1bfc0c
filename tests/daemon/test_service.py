"""``mushrooms run`` end to end: a real daemon process, the real mock Kafka
broker on loopback, real SQLite state, real sky maps and the greedy solver.

Whatever must happen "while a job is planning" happens while the job is
held by the test gate (``gated_run.py``: the job waits in front of its
scheduler until the test removes the hold), never in a race with a real
solve time.

The "updated sky map" of the supersede test is the mock event MS230425l's
preliminary notice (a different BAYESTAR map) with only its
``superevent_id`` rewritten to MS181101ab.
"""

from __future__ import annotations

import base64
import hashlib
import json
import signal
import sqlite3
import time
from pathlib import Path

from daemon_helpers import Daemon, notice_bytes, summary, write_config


def _held_gate(tmp_path: Path) -> Path:
    """A gate directory whose hold is already on (jobs wait from the first one)."""
    gate = tmp_path / "gate"
    gate.mkdir(exist_ok=True)
    (gate / "hold").touch()
    return gate


def _uniq(name: str) -> str:
    return f"{name}-{time.time_ns()}"


def _plans(messages, sid: str) -> list[dict]:
    return [m for m in messages if m.get("type") == "plan" and (m.get("event") or {}).get("superevent_id") == sid]


def _rows(state: Path, sql: str) -> list[tuple]:
    with sqlite3.connect(state) as c:
        return c.execute(sql).fetchall()


def _skymap_sha(raw: bytes) -> str:
    """SHA-256 of the map the service plans on: the joint map of an external coincidence, else the GW map."""
    d = json.loads(raw)
    joint = (d.get("external_coinc") or {}).get("combined_skymap")
    return hashlib.sha256(base64.b64decode(joint or d["event"]["skymap"])).hexdigest()


def test_kill9_in_the_middle_of_a_job_then_restart_delivers_the_same_plan(broker, daemons, tmp_path: Path) -> None:
    topic, out, group = _uniq("gwalert"), _uniq("plans"), _uniq("mushrooms")
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    state = tmp_path / "state.sqlite"
    args = ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)]
    raw_a = notice_bytes("MS181101ab-preliminary.json")
    produced = [broker.produce(topic, b"{not a notice", key=b"junk"),  # bad input never stops the service
                broker.produce(topic, raw_a, key=b"MS181101ab")]

    d1 = Daemon(tmp_path, args, gate=_held_gate(tmp_path))
    daemons.append(d1)
    d1.wait_held("MS181101ab")  # the job is in the middle of planning
    d1.kill9()
    assert "event=job_done" not in d1.text()
    assert "decision=rejected" in d1.text()
    assert _rows(state, "SELECT superevent_id, status FROM jobs") == [("MS181101ab", "running")]
    assert _rows(state, "SELECT count(*) FROM outbox") == [(0,)]

    # while the service is down another event arrives
    raw_b = notice_bytes("MS230425l-preliminary.json")
    produced.append(broker.produce(topic, raw_b, key=b"MS230425l"))
    d2 = Daemon(tmp_path, args)
    daemons.append(d2)
    reader = broker.reader(out, _uniq("reader"))
    try:
        msgs = reader.wait_for(lambda ms: _plans(ms, "MS181101ab") and _plans(ms, "MS230425l"), 300,
                               alive=d2.alive)
        plan_a = _plans(msgs, "MS181101ab")[0]
        assert "event=jobs_resumed count=1" in d2.text()
        # redelivery (as after a commit lost in a crash) is harmless: no new plan
        produced.append(broker.produce(topic, raw_a, key=b"MS181101ab"))
        d2.wait_log("decision=duplicate", 60)
        time.sleep(2)
        reader.wait_for(lambda ms: True, 1)
        msgs = reader.messages
    finally:
        reader.close()
    assert d2.stop() == 0
    assert {p["plan_id"] for p in _plans(msgs, "MS181101ab")} == {plan_a["plan_id"]}, summary(msgs)
    assert plan_a["event"]["skymap_sha256"] == _skymap_sha(raw_a)
    assert plan_a["observations"] and plan_a["metrics"]["solver"] == "greedy"

    # the plan delivered after the crash is the plan of an uninterrupted run:
    # recompute it from the stored horizon start with the same configuration
    from mushrooms.offline import configure_astropy_offline
    from mushrooms.tool.config import load_config
    from mushrooms.scheduler_core import EventInfo, make_plan, read_skymap
    from mushrooms.scheduler_core.plan.document import parse_time

    configure_astropy_offline()
    (start,) = _rows(state, "SELECT start FROM jobs WHERE superevent_id='MS181101ab'")[0]
    conf = load_config(cfg).scheduler
    fits = base64.b64decode(json.loads(raw_a)["event"]["skymap"])
    expected = make_plan(read_skymap(fits, nside=conf.nside), conf, start=parse_time(start),
                         event=EventInfo(superevent_id="MS181101ab"))
    assert expected.plan_id == plan_a["plan_id"]
    # and the same observations, not only the same id (the daemon's cached visibility is the direct one)
    assert [(o["field_id"], o["filter"], o["start"]) for o in expected.to_document()["observations"]] == [
        (o["field_id"], o["filter"], o["start"]) for o in plan_a["observations"]]

    # no notice skipped: every produced message is stored and every offset committed
    origins = {r[0] for r in _rows(state, "SELECT origin FROM notices")}
    assert origins == {f"kafka:{topic}:{p}:{o}" for p, o in produced}
    for part, (committed, high) in broker.committed(topic, group).items():
        assert committed == high or (high == 0 and committed < 0), (part, committed, high)


#: a creation time after every archived notice the tests relabel (MS230425l is of 2023-04-25)
LATER_THAN_2023 = "2023-04-26T00:00:00Z"


def test_updated_skymap_supersedes_the_running_job_and_retraction_withdraws(broker, daemons, tmp_path: Path) -> None:
    topic, out, group = _uniq("gwalert"), _uniq("plans"), _uniq("mushrooms")
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    state = tmp_path / "state.sqlite"
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)],
               gate=_held_gate(tmp_path))
    daemons.append(d)
    d.wait_log("event=service_ready", 60)
    first = notice_bytes("MS181101ab-preliminary.json")
    updated = notice_bytes("MS230425l-preliminary.json", superevent_id="MS181101ab")
    assert _skymap_sha(first) != _skymap_sha(updated)
    broker.produce(topic, first, key=b"MS181101ab")
    d.wait_held("MS181101ab")  # job 1 is planning
    broker.produce(topic, updated, key=b"MS181101ab")
    d.wait_log("event=job_superseded superevent_id=MS181101ab job=1 by_job=2", 60)
    d.wait_log("event=job_done superevent_id=MS181101ab job=1", 60)  # the stop ends job 1 although still held
    d.release()
    reader = broker.reader(out, _uniq("reader"))
    try:
        msgs = reader.wait_for(lambda ms: _plans(ms, "MS181101ab"), 300, alive=d.alive)
        text = d.wait_log("event=job_done superevent_id=MS181101ab job=1", 60)
        assert "stopped=superseded" in text.split("event=job_done superevent_id=MS181101ab job=1")[1].splitlines()[0]
        # dated after the relabelled 2023 notice it retracts (creation order)
        retraction = notice_bytes("MS181101ab-retraction.json", time_created=LATER_THAN_2023)
        broker.produce(topic, retraction, key=b"MS181101ab")
        msgs = reader.wait_for(lambda ms: any(m.get("type") == "withdrawal" for m in ms), 120, alive=d.alive)
        time.sleep(1)
        reader.wait_for(lambda ms: True, 1)
        msgs = reader.messages
    finally:
        reader.close()
    assert d.stop() == 0
    plans = _plans(msgs, "MS181101ab")
    assert len(plans) == 1, summary(msgs)  # the superseded job published nothing
    assert plans[0]["event"]["skymap_sha256"] == _skymap_sha(updated)
    (withdrawal,) = [m for m in msgs if m.get("type") == "withdrawal"]
    assert withdrawal["superevent_id"] == "MS181101ab"
    assert withdrawal["plan_ids"] == [plans[0]["plan_id"]]
    jobs = dict(_rows(state, "SELECT job_id, status FROM jobs"))
    assert jobs[1] == "superseded" and jobs[2] == "done"


def test_sigterm_during_a_job_leaves_it_pending_and_the_restart_finishes_it(broker, daemons, tmp_path: Path) -> None:
    topic, out, group = _uniq("gwalert"), _uniq("plans"), _uniq("mushrooms")
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    cfg.write_text(cfg.read_text().replace("[daemon]\n", "[daemon]\nstop_grace_s = 0.2\n"))
    state = tmp_path / "state.sqlite"
    args = ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)]
    broker.produce(topic, notice_bytes("MS181101ab-preliminary.json"), key=b"MS181101ab")
    d1 = Daemon(tmp_path, args, gate=_held_gate(tmp_path))
    daemons.append(d1)
    d1.wait_held("MS181101ab")  # the job is planning when SIGTERM arrives
    assert d1.stop(signal.SIGTERM) == 0
    text = d1.text()
    assert "event=service_stopped unfinished_jobs=yes" in text and "event=job_done" not in text
    # a clean stop is not a start that died: the job is pending again, its start not counted
    assert _rows(state, "SELECT status, attempts FROM jobs") == [("pending", 0)]
    for part, (committed, high) in broker.committed(topic, group).items():  # the notice itself was committed
        assert committed == high or (high == 0 and committed < 0)

    d2 = Daemon(tmp_path, args)
    daemons.append(d2)
    reader = broker.reader(out, _uniq("reader"))
    try:
        msgs = reader.wait_for(lambda ms: _plans(ms, "MS181101ab"), 300, alive=d2.alive)
    finally:
        reader.close()
    assert d2.stop() == 0
    assert "event=jobs_resumed count=1" in d2.text()
    assert len(_plans(msgs, "MS181101ab")) == 1
    assert _rows(state, "SELECT status FROM jobs") == [("done",)]
