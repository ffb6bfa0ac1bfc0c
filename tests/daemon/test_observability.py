"""Metrics, health, ``mushrooms status`` and offset-jump detection through the real daemon.

A real ``mushrooms run`` process on librdkafka's mock cluster (loopback);
the outbound topic lives on a second mock cluster in a process of its own so
that the test can SIGSTOP it (the outbound broker stops answering).  The
metrics are scraped over HTTP and parsed with prometheus-client's own text
parser.  Nothing here asserts a duration: every wait is for a state.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any, Callable

import confluent_kafka
from prometheus_client.parser import text_string_to_metric_families

from daemon_helpers import REPO, Daemon, notice_bytes, write_config

from mushrooms import __version__

BROKER_PROC = r"""
import confluent_kafka, time
p = confluent_kafka.Producer({"test.mock.num.brokers": 1, "message.max.bytes": 16000000, "log_level": 3})
b = next(iter(p.list_topics(timeout=10).brokers.values()))
print(f"{b.host}:{b.port}", flush=True)
while True:
    time.sleep(1)
"""


def _uniq(name: str) -> str:
    return f"{name}-{time.time_ns()}"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _get(port: int, path: str) -> tuple[int, str]:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=10) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode()


def _scrape(port: int) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Sample (name, sorted labels) -> value, parsed by prometheus-client's parser."""
    status, text = _get(port, "/metrics")
    assert status == 200
    out = {}
    for fam in text_string_to_metric_families(text):
        for s in fam.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


def _value(samples: dict, name: str, **labels: str) -> float:
    return samples.get((name, tuple(sorted(labels.items()))), 0.0)


def _wait(cond: Callable[[], Any], timeout_s: float, d: Daemon | None = None, what: str = "") -> Any:
    end = time.monotonic() + timeout_s
    while True:
        got = cond()
        if got:
            return got
        if d is not None:
            d.alive()
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}" + (f":\n{d.text()[-3000:]}" if d else ""))
        time.sleep(0.2)


def _status(state: Path, *extra: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", "status", "--state", str(state), *extra],
                          capture_output=True, text=True, env=env, timeout=120)


def _final_plans(reader: Any, sids: set[str]) -> bool:
    got = {(m.get("event") or {}).get("superevent_id") for m in reader.messages
           if m.get("type") in ("plan", "not_observable") and m.get("final")}
    return sids <= got


def test_metrics_health_and_status_through_the_daemon(broker, daemons, tmp_path: Path) -> None:
    bp = subprocess.Popen([sys.executable, "-c", BROKER_PROC], stdout=subprocess.PIPE, text=True)
    try:
        out_bootstrap = bp.stdout.readline().strip()
        topic, out, group = _uniq("gwalert"), _uniq("plans"), _uniq("mushrooms")
        broker.ensure_topic(topic)
        port = _free_port()
        cfg = write_config(tmp_path / "config.toml", topic, out, group)
        cfg.write_text(cfg.read_text()
                       .replace("[daemon]\n", f'[daemon]\nmetrics_address = "127.0.0.1:{port}"\n')
                       .replace("[outbound]\n", f'[outbound]\nbootstrap = "{out_bootstrap}"\ndelivery_timeout_s = 2\n'))
        state = tmp_path / "state.sqlite"
        gate = tmp_path / "gate"
        gate.mkdir()
        (gate / "hold-warm").touch()
        d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)], gate=gate)
        daemons.append(d)

        # warm-up held: alive, not ready, and the body says why (the listener opens a moment
        # before the warm-up starts: under load /healthz may still say "starting" at first)
        d.wait_log("event=metrics_listening", 120)
        _wait(lambda: json.loads(_get(port, "/healthz")[1]).get("phase") == "warming", 60, d, "warming")
        code, body = _get(port, "/readyz")
        assert code == 503, body
        ready = json.loads(body)
        assert ready["ready"] is False and "warm_up" in ready["failed"] and "partitions" in ready["failed"]
        assert ready["checks"]["store"]["ok"] is True
        code, body = _get(port, "/healthz")
        assert code == 200 and json.loads(body)["phase"] == "warming"
        (gate / "hold-warm").unlink()
        d.wait_log("event=service_ready", 120)
        _wait(lambda: _get(port, "/readyz")[0] == 200, 60, d, "ready")
        ready = json.loads(_get(port, "/readyz")[1])
        assert ready["failed"] == [] and set(ready["checks"]) == {"warm_up", "partitions", "store", "broker",
                                                                  "outbound"}

        # two notices and one bad message
        admin = confluent_kafka.Producer({"bootstrap.servers": out_bootstrap, "log_level": 3})
        admin.list_topics(out, timeout=10)
        from daemon_helpers import Reader

        reader = Reader(out_bootstrap, out, _uniq("reader"))
        broker.produce(topic, notice_bytes("MS181101ab-preliminary.json"), key=b"MS181101ab")
        broker.produce(topic, notice_bytes("MS230425l-preliminary.json"), key=b"MS230425l")
        broker.produce(topic, b"{not a notice", key=b"junk")
        reader.wait_for(lambda ms: _final_plans(reader, {"MS181101ab", "MS230425l"}), 300, alive=d.alive)
        m = _wait(lambda: (lambda s: s if _value(s, "mushrooms_first_plan_latency_seconds_count") == 2 else None)(
            _scrape(port)), 30, d, "two first plans counted")
        assert _value(m, "mushrooms_notices_total", source="kafka", alert_type="PRELIMINARY", decision="plan") == 2
        assert _value(m, "mushrooms_notices_total", source="kafka", alert_type="none", decision="rejected") == 1
        assert _value(m, "mushrooms_messages_rejected_total", reason="undecodable") == 1
        assert _value(m, "mushrooms_messages_rejected_total", reason="schema") == 0
        assert _value(m, "mushrooms_final_plan_latency_seconds_count") == 2  # greedy: revision 1 is final
        assert _value(m, "mushrooms_first_plan_latency_seconds_sum") > 0
        assert _value(m, "mushrooms_first_plan_latency_seconds_bucket", le="+Inf") == 2
        assert _value(m, "mushrooms_plan_revisions_published_total", revision="1") == 2
        assert _value(m, "mushrooms_plan_revisions_published_total", revision="2") == 0
        assert _value(m, "mushrooms_published_messages_total", type="plan") == 2
        assert _value(m, "mushrooms_jobs_finished_total", result="done") == 2
        assert _value(m, "mushrooms_jobs_failed_total") == 0
        assert _value(m, "mushrooms_jobs", state="queued") == 0 and _value(m, "mushrooms_jobs", state="running") == 0
        assert _value(m, "mushrooms_outbox_pending_messages") == 0
        assert _value(m, "mushrooms_outbox_oldest_pending_age_seconds") == 0
        assert _value(m, "mushrooms_broker_up", client="consumer") == 1
        assert _value(m, "mushrooms_state_file_bytes", file="db") > 0
        assert _value(m, "mushrooms_submissions_total", result="submitted") == 0
        assert _value(m, "mushrooms_executed_observations_last_read_timestamp_seconds") == 0
        assert any(k[0] == "mushrooms_build_info" and ("version", __version__) in k[1] for k in m)
        _wait(lambda: _value(_scrape(port), "mushrooms_broker_up", client="sink") == 1, 30, d, "sink stats")
        _wait(lambda: ("mushrooms_consumer_lag_messages", (("topic", topic),)) in _scrape(port), 30, d, "lag")

        # status while the daemon runs: both events, published, nothing wrong
        r = _status(state)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "MS181101ab" in r.stdout and "MS230425l" in r.stdout and "published" in r.stdout
        assert "nothing needs attention" in r.stdout
        doc = json.loads(_status(state, "--json").stdout)
        ev = {e["superevent_id"]: e for e in doc["events"]}
        assert ev["MS181101ab"]["alert_types"] == ["PRELIMINARY"] and ev["MS181101ab"]["decision"] == "plan"
        (plan,) = ev["MS181101ab"]["plans"]
        assert plan["published"] and plan["revision"] == 1 and 0 < plan["coverage"] <= 1

        # a job that fails: metrics and status say so (exit 1)
        (gate / "fail").touch()
        broker.produce(topic, notice_bytes("MS181101ab-preliminary.json", superevent_id="MS181101zz"),
                       key=b"MS181101zz")
        d.wait_log("event=job_done superevent_id=MS181101zz", 120)
        (gate / "fail").unlink()
        _wait(lambda: _value(_scrape(port), "mushrooms_jobs_failed_total") == 1, 30, d, "failed job counted")
        r = _status(state)
        assert r.returncode == 1, r.stdout + r.stderr
        assert "NEEDS ATTENTION" in r.stdout and "MS181101zz failed" in r.stdout

        # the outbound broker stops answering: readiness says so and the backlog grows
        os.kill(bp.pid, signal.SIGSTOP)
        try:
            broker.produce(topic, notice_bytes("MS230425l-preliminary.json", superevent_id="MS230425zz"),
                           key=b"MS230425zz")
            d.wait_log("event=job_done superevent_id=MS230425zz", 120)
            body = _wait(lambda: (lambda r: r[1] if r[0] == 503 else None)(_get(port, "/readyz")), 120, d,
                         "readiness to fail")
            ready = json.loads(body)
            assert ready["failed"] == ["outbound"], ready
            assert "pending" in ready["checks"]["outbound"]["detail"]
            m1 = _scrape(port)
            assert _value(m1, "mushrooms_outbox_pending_messages") >= 1
            age1 = _value(m1, "mushrooms_outbox_oldest_pending_age_seconds")
            m2 = _wait(lambda: (lambda s: s if _value(s, "mushrooms_outbox_oldest_pending_age_seconds") > age1
                                else None)(_scrape(port)), 30, d, "the backlog to age")
            assert _value(m2, "mushrooms_outbox_pending_messages") >= 1
            assert _value(m2, "mushrooms_published_messages_total", type="plan") == 2  # nothing went out
        finally:
            os.kill(bp.pid, signal.SIGCONT)
        reader.wait_for(lambda ms: _final_plans(reader, {"MS230425zz"}), 300, alive=d.alive)
        _wait(lambda: _get(port, "/readyz")[0] == 200, 120, d, "ready again")
        m = _scrape(port)
        assert _value(m, "mushrooms_outbox_pending_messages") == 0
        assert _value(m, "mushrooms_first_plan_latency_seconds_count") == 3
        reader.close()
        assert d.stop() == 0
    finally:
        try:
            os.kill(bp.pid, signal.SIGCONT)
        except ProcessLookupError:
            pass
        bp.kill()
        bp.wait(10)


def test_offset_jump_past_deleted_messages_is_an_error_counted_and_shown(broker, daemons, tmp_path: Path) -> None:
    topic, out, group = _uniq("gwalert"), _uniq("plans"), _uniq("mushrooms")
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    port = _free_port()
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    cfg.write_text(cfg.read_text().replace("[daemon]\n", f'[daemon]\nmetrics_address = "127.0.0.1:{port}"\n'))
    state = tmp_path / "state.sqlite"
    args = ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)]
    part, first = broker.produce(topic, notice_bytes("MS181101ab-preliminary.json"), key=b"MS181101ab")
    d1 = Daemon(tmp_path, args)
    daemons.append(d1)
    d1.wait_log("event=job_done superevent_id=MS181101ab", 300)
    assert d1.stop() == 0
    assert "event=offset_jump" not in d1.text()
    # while the service is down, the partition fills past the mock broker's retention (about 5 MB):
    # the committed position (first + 1) and the notices after it are deleted
    blob = os.urandom(1_000_000)
    produced = [broker.produce(topic, blob, key=b"MS181101ab")[1] for _ in range(7)]
    c = confluent_kafka.Consumer({"bootstrap.servers": broker.bootstrap, "group.id": _uniq("probe")})
    low, high = c.get_watermark_offsets(confluent_kafka.TopicPartition(topic, part), timeout=10, cached=False)
    c.close()
    assert low > first + 1 and high == produced[-1] + 1
    d2 = Daemon(tmp_path, args)
    daemons.append(d2)
    text = d2.wait_log("event=offset_jump", 120)
    line = next(x for x in text.splitlines() if "event=offset_jump" in x)
    assert "ERROR" in line and f"expected={first + 1} got={low} skipped={low - first - 1}" in line
    d2.wait_log("event=metrics_listening", 60)
    m = _wait(lambda: (lambda s: s if _value(s, "mushrooms_consumer_offset_jumps_total", topic=topic) else None)(
        _scrape(port)), 60, d2, "the jump counted")
    assert _value(m, "mushrooms_consumer_skipped_messages_total", topic=topic) == low - first - 1
    r = _status(state)
    assert r.returncode == 1, r.stdout + r.stderr
    assert f"{low - first - 1} message(s) of {topic}[{part}] skipped" in r.stdout
    # the messages that are left are read: no second jump
    d2.wait_log("event=notice origin=kafka:", 60, count=high - low)
    assert d2.stop() == 0
    assert d2.text().count("event=offset_jump") == 1


def test_readiness_and_ready_wait_for_the_group_to_assign_partitions(broker, daemons, tmp_path: Path) -> None:
    """The finding: ``service_ready`` long before ``partitions_assigned`` in group mode.

    A member of the group has just left it (as a daemon stopping for a
    restart does); librdkafka's mock coordinator then holds the next join
    for ``session_timeout_s - 1`` s.  Readiness and systemd's READY=1 must
    say "not consuming" for exactly that wait.
    """
    topic, out, group = _uniq("gwalert"), _uniq("plans"), _uniq("mushrooms")
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    port = _free_port()
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    cfg.write_text(cfg.read_text().replace('assignment = "manual"', 'assignment = "group"')
                   .replace("[daemon]\n", f'[daemon]\nmetrics_address = "127.0.0.1:{port}"\n'))
    from mushrooms.daemon.kafka.consumer import consumer_config
    from mushrooms.daemon.settings import KafkaConfig

    # the previous member: joins, gets the partitions, leaves cleanly
    prev = confluent_kafka.Consumer(consumer_config(KafkaConfig(topics=(topic,), group_id=group,
                                                                bootstrap=broker.bootstrap)) | {"log_level": 3})
    got: list[Any] = []
    prev.subscribe([topic], on_assign=lambda c, parts: got.extend(parts))
    _wait(lambda: prev.consume(1, 0.2) is not None and got, 60, what="the first member's assignment")
    prev.close()
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(str(tmp_path / "notify.sock"))
    notify.settimeout(0.2)
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state",
                          str(tmp_path / "state.sqlite")], env={"NOTIFY_SOCKET": str(tmp_path / "notify.sock")})
    daemons.append(d)
    text = d.wait_log("event=service_ready", 120)
    assert "partitions=waiting" in text.split("event=service_ready")[1].splitlines()[0]
    seen: list[bytes] = []
    waiting: list[dict] = []
    while b"READY=1" not in b"".join(seen):  # READY=1 only once the partitions are there
        try:
            seen.append(notify.recv(4096))
        except (socket.timeout, BlockingIOError):
            pass
        code, body = _get(port, "/readyz")
        if "event=consuming" not in d.text():
            if code == 503:
                waiting.append(json.loads(body))
        d.alive()
    ready_msg = next(m for m in seen if m.startswith(b"READY=1"))
    assert b"STATUS=consuming" in ready_msg, seen
    assert "event=consuming partitions=" in d.text()  # logged before READY=1 was sent
    assert waiting and all("partitions" in w["failed"] for w in waiting)
    assert "no partitions assigned yet" in waiting[-1]["checks"]["partitions"]["detail"]
    _wait(lambda: _get(port, "/readyz")[0] == 200, 60, d, "ready")
    assert d.stop() == 0
    notify.close()
