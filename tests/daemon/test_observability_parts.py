"""The parts of the observability work on their own: metrics registry, status on a real state file,
the consumer's offset-jump detection on the mock broker, the listener's paths."""

from __future__ import annotations

import json
import os
import sqlite3
import time
import urllib.error
import urllib.request
from pathlib import Path

import confluent_kafka
import pytest
from prometheus_client.parser import text_string_to_metric_families

from daemon_helpers import notice_bytes

from mushrooms.cli import main as cli_main
from mushrooms.daemon.kafka.consumer import NoticeConsumer
from mushrooms.daemon.ops.health import HealthServer, liveness, store_check
from mushrooms.daemon.ops.metrics import REJECTION_CLASSES, ServiceMetrics, rejection_class
from mushrooms.daemon.settings import KafkaConfig, parse_address
from mushrooms.daemon.state.store import NoticeRecord, Store
from mushrooms.handlers.alert import NoticeError, parse_notice
from mushrooms.handlers.decisions import Decision


def _samples(metrics: ServiceMetrics) -> dict:
    out = {}
    for fam in text_string_to_metric_families(metrics.render().decode()):
        for s in fam.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


class _Acc:  # the fields of the pipeline's Accepted that the metrics read
    def __init__(self, action: str, alert_type: str | None, reason: str = "") -> None:
        self.action, self.alert_type, self.reason = action, alert_type, reason


def test_each_daemon_has_its_own_registry(tmp_path: Path) -> None:
    a, b = ServiceMetrics("1.0"), ServiceMetrics("1.0")
    a.notice(_Acc("plan", "PRELIMINARY"))
    a.notice(None)  # quarantined
    sa, sb = _samples(a), _samples(b)
    key = ("mushrooms_notices_total", (("alert_type", "PRELIMINARY"), ("decision", "plan"), ("source", "kafka")))
    assert sa[key] == 1 and key not in sb
    assert sa[("mushrooms_messages_quarantined_total", ())] == 1 and sb[("mushrooms_messages_quarantined_total", ())] == 0
    # and nothing of ours went into prometheus-client's global registry
    from prometheus_client import REGISTRY

    assert not [m for m in REGISTRY.collect() if m.name.startswith("mushrooms_")]


@pytest.mark.parametrize("raw, expected", [
    (b"{not json", "undecodable"),
    (b"", "undecodable"),
    (b"\xff\xfe", "undecodable"),
    (b"x" * 2000, "too_large"),
    (b'{"superevent_id": "S1", "alert_type": "PRELIMINARY"}', "schema"),
    (b'{"superevent_id": "S1", "alert_type": "NOPE", "time_created": "2024-01-01T00:00:00Z"}', "schema"),
])
def test_rejection_reasons_of_the_real_parser_fall_in_few_classes(raw: bytes, expected: str) -> None:
    with pytest.raises(NoticeError) as err:
        parse_notice(raw, max_bytes=1000)
    assert rejection_class(str(err.value)) == expected
    assert expected in REJECTION_CLASSES


def test_bad_sky_map_and_policy_failures_have_their_class() -> None:
    doc = json.loads(notice_bytes("MS230425l-preliminary.json"))
    doc["event"]["skymap"] = "not base64 !!"
    with pytest.raises(NoticeError) as err:
        parse_notice(json.dumps(doc).encode())
    assert rejection_class(str(err.value)) == "skymap"
    assert rejection_class("policy evaluation failed: KeyError: 'x'") == "policy_error"


def test_published_messages_fill_the_latency_histograms() -> None:
    m = ServiceMetrics("1.0")
    now = 1000.0
    m.published_message({"type": "plan", "revision": 1, "final": False, "plan_id": "a"}, 990.0, now)
    m.published_message({"type": "plan", "revision": 2, "final": True, "plan_id": "b"}, 970.0, now)
    m.published_message({"type": "plan_final", "plan_id": "c"}, 940.0, now)
    m.published_message({"type": "withdrawal", "withdrawal_id": "w"}, None, now)
    s = _samples(m)
    assert s[("mushrooms_first_plan_latency_seconds_count", ())] == 1
    assert s[("mushrooms_first_plan_latency_seconds_sum", ())] == 10.0
    assert s[("mushrooms_final_plan_latency_seconds_count", ())] == 2
    assert s[("mushrooms_final_plan_latency_seconds_sum", ())] == 90.0
    assert s[("mushrooms_first_plan_latency_seconds_bucket", (("le", "10.0"),))] == 1
    assert s[("mushrooms_first_plan_latency_seconds_bucket", (("le", "7.5"),))] == 0
    assert s[("mushrooms_plan_revisions_published_total", (("revision", "2"),))] == 1
    assert s[("mushrooms_published_messages_total", (("type", "withdrawal"),))] == 1


def test_hooks_for_submission_and_observation_reads() -> None:
    m = ServiceMetrics("1.0")
    s = _samples(m)
    assert s[("mushrooms_submissions_total", (("result", "rejected"),))] == 0  # at zero until used
    m.submission("rejected")
    m.observations_read(when=1234.5)
    s = _samples(m)
    assert s[("mushrooms_submissions_total", (("result", "rejected"),))] == 1
    assert s[("mushrooms_executed_observations_last_read_timestamp_seconds", ())] == 1234.5


def _state_with_a_plan(path: Path, published: bool = True) -> Store:
    """A real state file: one notice, its decision, its job and one published plan revision."""
    store = Store(path)
    rec = NoticeRecord(origin="kafka:t:0:0", sha256="0" * 64, size=10, received_at="2026-01-01T00:00:00.000Z",
                       superevent_id="S260101a", alert_type="PRELIMINARY", raw=b"{}")
    nid, _, job, _, _ = store.record_decision(
        rec, lambda ledger: Decision("plan", "S260101a", "significant BNS", "PRELIMINARY", "a" * 64),
        lambda d: "2026-01-01T00:00:00.000Z", received_wall=time.time())
    assert job is not None
    store.start_job(job.job_id)
    doc = {"type": "plan", "plan_id": "plan-1", "revision": 1, "final": True,
           "metrics": {"coverage": 0.42, "expected_detections": 0.17}}
    outbox_id = store.store_revision(job.job_id, "plan-1", doc, 0.42, 1.0, final=True, revision=1)
    if published:
        store.mark_published(outbox_id)
    return store


def test_status_reads_a_state_file_and_tolerates_tables_it_does_not_know(tmp_path: Path, capsys) -> None:
    state = tmp_path / "state.sqlite"
    store = _state_with_a_plan(state)
    assert cli_main(["status", "--state", str(state)]) == 0
    out = capsys.readouterr().out
    assert "S260101a" in out and "coverage 0.4200, expected detections 0.1700, published" in out
    assert "nothing needs attention" in out
    # a state file of a release without the submissions and incidents tables is read as well
    with sqlite3.connect(state) as c:
        c.execute("DROP TABLE submissions")
        c.execute("DROP TABLE incidents")  # a file no daemon of this version opened
    assert cli_main(["status", "--state", str(state), "--json"]) == 0
    (plan,) = json.loads(capsys.readouterr().out)["events"][0]["plans"]
    assert plan["submission"] is None and plan["published"] is True
    # the submissions table (the store's own schema) is shown beside the plan
    with sqlite3.connect(state) as c:
        c.execute("CREATE TABLE submissions (plan_id TEXT PRIMARY KEY, superevent_id TEXT NOT NULL, "
                  "target TEXT NOT NULL, revision INTEGER, queue_name TEXT UNIQUE, state TEXT NOT NULL, "
                  "created_at TEXT NOT NULL)")
        c.execute("INSERT INTO submissions(plan_id, superevent_id, target, revision, queue_name, state, created_at)"
                  " VALUES ('plan-1', 'S260101a', 'kowalski', 1, 'ToO_GW_S260101a_r1', 'submitted',"
                  " '2026-01-01T00:00:01.000Z')")
    assert cli_main(["status", "--state", str(state), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (plan,) = doc["events"][0]["plans"]
    assert plan["submission"]["state"] == "submitted" and plan["published"] is True
    assert doc["offset_jumps"] == [] and doc["attention"] == []
    store.close()


def test_status_exit_1_on_a_failed_job_an_old_outbox_row_and_a_notice_without_decision(tmp_path: Path,
                                                                                         capsys) -> None:
    state = tmp_path / "state.sqlite"
    store = _state_with_a_plan(state, published=False)
    assert cli_main(["status", "--state", str(state)]) == 0  # pending, but not yet old
    capsys.readouterr()
    with sqlite3.connect(state) as c:
        c.execute("UPDATE outbox SET created_at='2020-01-01T00:00:00.000+00:00', last_error='broker down'")
    assert cli_main(["status", "--state", str(state)]) == 1
    out = capsys.readouterr().out
    assert "NEEDS ATTENTION (1)" in out and "unpublished for" in out and "broker down" in out
    with sqlite3.connect(state) as c:
        c.execute("INSERT INTO notices(received_at, origin, sha256, size) VALUES ('2026-01-01T00:00:00Z',"
                  " 'kafka:t:0:9', 'b', 1)")
        c.execute("UPDATE jobs SET status='failed', reason='internal error: boom', finished_at=NULL")
    store.record_incident("offset_jump", {"topic": "t", "partition": 0, "expected": 1, "got": 5, "skipped": 4,
                                          "cause": "retention"})
    assert cli_main(["status", "--state", str(state), "--json"]) == 1
    lines = json.loads(capsys.readouterr().out)["attention"]
    assert len(lines) == 4
    assert any("failed: internal error: boom" in x for x in lines)
    assert any("has no decision" in x for x in lines)
    assert any("4 message(s) of t[0] skipped" in x for x in lines)
    store.close()


def test_status_refuses_what_is_not_a_state_file(tmp_path: Path, capsys) -> None:
    assert cli_main(["status", "--state", str(tmp_path / "missing.sqlite")]) == 2
    assert "no such state file" in capsys.readouterr().err
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"not a database at all" * 100)
    assert cli_main(["status", "--state", str(junk)]) == 2
    assert "not a readable mushrooms state file" in capsys.readouterr().err


def test_status_does_not_write_the_state_file(tmp_path: Path, capsys) -> None:
    state = tmp_path / "state.sqlite"
    store = _state_with_a_plan(state)
    with sqlite3.connect(state) as c:
        before = c.execute("PRAGMA data_version").fetchone()[0], state.read_bytes()
    store.close()
    os.chmod(state, 0o400)
    try:
        assert cli_main(["status", "--state", str(state)]) == 0
    finally:
        os.chmod(state, 0o600)
    assert state.read_bytes() == before[1]


def test_consumer_reports_a_committed_offset_deleted_by_retention(broker) -> None:
    topic, group = f"jump-{time.time_ns()}", f"g-{time.time_ns()}"
    broker.ensure_topic(topic)
    part, first = broker.produce(topic, b"first", key=b"k")
    cfg = KafkaConfig(topics=(topic,), group_id=group, bootstrap=broker.bootstrap, assignment="manual",
                      poll_timeout_s=0.5)
    jumps: list[tuple] = []
    c1 = NoticeConsumer(cfg, on_offset_jump=lambda *a: jumps.append(a))
    got = None
    for _ in range(40):
        got = c1.poll()
        if got is not None:
            break
    assert got is not None and got.origin == f"kafka:{topic}:{part}:{first}"
    c1.commit(got)
    c1.close()
    blob = os.urandom(1_000_000)
    for _ in range(7):  # past the mock broker's ~5 MB per partition: the oldest messages go
        broker.produce(topic, blob, key=b"k")
    probe = confluent_kafka.Consumer({"bootstrap.servers": broker.bootstrap, "group.id": "probe"})
    low, _ = probe.get_watermark_offsets(confluent_kafka.TopicPartition(topic, part), timeout=10, cached=False)
    probe.close()
    assert low > first + 1
    c2 = NoticeConsumer(cfg, on_offset_jump=lambda *a: jumps.append(a))
    assert jumps == [(topic, part, first + 1, low, low - first - 1,
                      "committed offset below the log start: deleted by retention before it was read")]
    assert (topic, part) in c2.assigned and c2.waiting_since is None
    nxt = None
    for _ in range(40):
        nxt = c2.poll()
        if nxt is not None:
            break
    assert nxt is not None and nxt.origin.endswith(f":{low}")
    assert len(jumps) == 1  # reading on from the log start is no second jump
    c2.close()


def test_listener_paths_and_liveness(tmp_path: Path) -> None:
    m = ServiceMetrics("9.9", tmp_path / "state.sqlite")
    Store(tmp_path / "state.sqlite").close()
    phase = {"p": "running", "age": 1.0}
    server = HealthServer("127.0.0.1", 0, m, liveness(lambda: phase["p"], lambda: phase["age"], 30.0),
                          {"store": store_check(tmp_path / "state.sqlite")}).start()
    host, port = server.address

    def get(path: str) -> tuple[int, str]:
        try:
            with urllib.request.urlopen(f"http://{host}:{port}{path}", timeout=10) as r:
                return r.status, r.read().decode()
        except urllib.error.HTTPError as e:
            return e.code, e.read().decode()

    try:
        assert get("/healthz")[0] == 200
        phase["age"] = 31.0  # the loop has not turned within the limit
        code, body = get("/healthz")
        assert code == 503 and json.loads(body)["alive"] is False
        assert get("/readyz")[0] == 200
        server.add_check("submission", lambda: (False, "queue unreachable"))
        code, body = get("/readyz")
        assert code == 503 and json.loads(body)["failed"] == ["submission"]
        server.add_check("broken", lambda: 1 / 0)
        assert "ZeroDivisionError" in json.loads(get("/readyz")[1])["checks"]["broken"]["detail"]
        code, text = get("/metrics")
        assert code == 200 and 'mushrooms_build_info{' in text and "mushrooms_outbox_pending_messages 0.0" in text
        assert get("/nope")[0] == 404
    finally:
        server.close()


def test_metrics_address_is_checked_at_load() -> None:
    assert parse_address("127.0.0.1:9464") == ("127.0.0.1", 9464)
    assert parse_address("[::1]:9464") == ("::1", 9464)
    assert parse_address(":9464") == ("0.0.0.0", 9464)
    for bad in ("9464", "host:", "host:99999", "host:port"):
        with pytest.raises(ValueError):
            parse_address(bad)
