"""The service's parts on their own: sd_notify, credentials, paths, pid lock,
trigger files, the Kafka sink and the consumer against the real mock broker,
and the systemd unit."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
from pathlib import Path

import pytest

from mushrooms.daemon.kafka.consumer import NoticeConsumer
from mushrooms.daemon.credentials import CredentialsError, load_credentials
from mushrooms.daemon.kafka.sink import KafkaSink, PublishError
from mushrooms.daemon.ops.systemd import Notifier, watchdog_interval_s
from mushrooms.daemon.settings import DaemonConfig, KafkaConfig, OutboundConfig, resolve_paths
from mushrooms.daemon.intake.trigger import (
    DaemonRunning, PidLock, classify, daemon_pid, pending_triggers, read_trigger, write_trigger,
)
from mushrooms.scheduler_core.errors import InputError

from daemon_helpers import REPO, notice_bytes, notice_path


# ---------------------------------------------------------------- sd_notify
def test_notifier_sends_datagrams_to_the_socket(tmp_path: Path) -> None:
    path = str(tmp_path / "notify.sock")
    server = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    server.bind(path)
    server.settimeout(5)
    try:
        n = Notifier(path)
        assert n.enabled
        assert n.ready("consuming igwn.gwalert")
        assert server.recv(4096) == b"READY=1\nSTATUS=consuming igwn.gwalert"
        assert n.watchdog()
        assert server.recv(4096) == b"WATCHDOG=1"
        assert n.stopping()
        assert server.recv(4096) == b"STOPPING=1"
    finally:
        server.close()


def test_notifier_is_a_noop_outside_systemd() -> None:
    n = Notifier("")
    assert not n.enabled
    assert not n.ready()


def test_watchdog_interval_is_half_of_watchdog_sec() -> None:
    assert watchdog_interval_s({"WATCHDOG_USEC": "60000000"}) == 30.0
    assert watchdog_interval_s({"WATCHDOG_USEC": "60000000", "WATCHDOG_PID": "1"}) is None
    assert watchdog_interval_s({}) is None


# ---------------------------------------------------------------- credentials
def test_credentials_from_systemd_win_over_environment(tmp_path: Path) -> None:
    (tmp_path / "gcn_client_secret").write_text("s3cret\n")
    env = {"CREDENTIALS_DIRECTORY": str(tmp_path), "GCN_CLIENT_ID": "abc", "GCN_CLIENT_SECRET": "envsecret"}
    c = load_credentials(env)
    assert (c.client_id, c.client_secret) == ("abc", "s3cret")
    assert "credential:gcn_client_secret" in c.source
    assert "s3cret" not in repr(c)


def test_credentials_from_environment_and_missing() -> None:
    c = load_credentials({"GCN_CLIENT_ID": "abc", "GCN_CLIENT_SECRET": "xyz"})
    assert c.client_secret == "xyz"
    with pytest.raises(CredentialsError, match="client secret"):
        load_credentials({"GCN_CLIENT_ID": "abc"})


# ---------------------------------------------------------------- settings
def test_settings_reject_unknown_keys_and_bad_values() -> None:
    with pytest.raises(ValueError, match="unknown"):
        KafkaConfig.from_mapping({"topic": "x"})
    with pytest.raises(ValueError, match="assignment"):
        KafkaConfig.from_mapping({"assignment": "static"})
    with pytest.raises(ValueError, match="max_jobs"):
        DaemonConfig.from_mapping({"max_jobs": 0})
    assert KafkaConfig.from_mapping({"topics": ["a", "b"]}).topics == ("a", "b")
    assert OutboundConfig().sink == "directory"


def test_paths_follow_the_state_file(tmp_path: Path) -> None:
    p = resolve_paths(DaemonConfig(state_path=str(tmp_path / "s" / "state.sqlite")), {})
    assert p.trigger_dir == tmp_path / "s" / "mushrooms-triggers"
    assert p.pid_file == tmp_path / "s" / "mushrooms.pid"
    q = resolve_paths(DaemonConfig(), {"STATE_DIRECTORY": str(tmp_path)})
    assert q.state == tmp_path / "mushrooms-state.sqlite"


# ---------------------------------------------------------------- pid lock and trigger files
def test_pid_lock_tells_a_live_daemon_from_a_stale_file(tmp_path: Path) -> None:
    pid_file = tmp_path / "mushrooms.pid"
    pid_file.write_text("999999\n")  # stale: nobody holds the lock
    assert daemon_pid(pid_file) is None
    lock = PidLock(pid_file)
    lock.acquire()
    try:
        assert daemon_pid(pid_file) == os.getpid()
        with pytest.raises(DaemonRunning):
            PidLock(pid_file).acquire()
    finally:
        lock.release()
    assert not pid_file.exists()
    assert daemon_pid(pid_file) is None


def test_classify_and_trigger_files(tmp_path: Path) -> None:
    kind, data = classify(str(notice_path("MS181101ab-retraction.json")))
    assert kind == "notice" and data.startswith(b"{")
    fits = REPO / "mushrooms" / "scheduler_core" / "data" / "MS181101ab_bayestar.multiorder.fits"
    assert classify(str(fits))[0] == "skymap"
    assert classify("S250101ab") == ("superevent", b"S250101ab")
    with pytest.raises(InputError):
        classify("no-such-thing.json")
    d = tmp_path / "triggers"
    a = write_trigger(d, "superevent", b"MS181101ab")
    time.sleep(0.001)
    b = write_trigger(d, "notice", data)
    (d / ".half-written.tmp").write_bytes(b"x")
    assert pending_triggers(d) == [a, b]
    assert read_trigger(b) == ("notice", data)


# ---------------------------------------------------------------- Kafka sink and consumer
def test_kafka_sink_publishes_a_large_message(broker) -> None:
    topic = f"sink-{time.time_ns()}"
    broker.ensure_topic(topic)
    sink = KafkaSink(broker.bootstrap, topic, delivery_timeout_s=20)
    big = {"type": "plan", "plan_id": "p1", "event": {"superevent_id": "S1"},
           "observations": [{"field_id": i, "pad": "x" * 1000} for i in range(2000)]}  # ~2 MB
    sink.publish(big)
    sink.close()
    reader = broker.reader(topic, "sink-reader")
    try:
        got = reader.wait_for(lambda ms: len(ms) >= 1, 30)
    finally:
        reader.close()
    assert got[0]["plan_id"] == "p1" and len(got[0]["observations"]) == 2000


def test_kafka_sink_raises_when_the_broker_is_unreachable() -> None:
    with socket.socket() as s:  # a closed loopback port
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    sink = KafkaSink(f"127.0.0.1:{port}", "nowhere", delivery_timeout_s=2)
    with pytest.raises(PublishError):
        sink.publish({"type": "withdrawal", "superevent_id": "S1"})


def test_outbound_security_settings_and_password_lookup(tmp_path: Path) -> None:
    from mushrooms.daemon.kafka.sink import sink_security

    assert sink_security(OutboundConfig(sink="kafka"), {}) == ({"security.protocol": "plaintext"}, "plaintext")
    assert sink_security(OutboundConfig(sink="kafka", security_protocol="SSL"), {})[0] == {"security.protocol": "ssl"}
    sasl = OutboundConfig(sink="kafka", security_protocol="sasl_ssl", sasl_username="ztf-planner",
                          sasl_mechanism="scram-sha-256")
    conf, described = sink_security(sasl, {"MUSHROOMS_OUTBOUND_PASSWORD": "hunter2\n"})
    assert conf == {"security.protocol": "sasl_ssl", "sasl.mechanism": "SCRAM-SHA-256",
                    "sasl.username": "ztf-planner", "sasl.password": "hunter2"}
    assert "hunter2" not in described and "env:MUSHROOMS_OUTBOUND_PASSWORD" in described
    # a systemd credential wins over the environment
    (tmp_path / "outbound_password").write_text("from-systemd\n")
    conf, described = sink_security(sasl, {"CREDENTIALS_DIRECTORY": str(tmp_path),
                                           "MUSHROOMS_OUTBOUND_PASSWORD": "hunter2"})
    assert conf["sasl.password"] == "from-systemd" and "credential:outbound_password" in described
    with pytest.raises(CredentialsError, match="MUSHROOMS_OUTBOUND_PASSWORD"):
        sink_security(sasl, {})
    with pytest.raises(CredentialsError, match="sasl_username"):
        sink_security(OutboundConfig(sink="kafka", security_protocol="sasl_ssl"), {"MUSHROOMS_OUTBOUND_PASSWORD": "x"})
    with pytest.raises(ValueError, match="security_protocol"):
        OutboundConfig.from_mapping({"security_protocol": "tls"})
    with pytest.raises(ValueError, match="sasl_mechanism"):
        OutboundConfig.from_mapping({"sasl_mechanism": "GSSAPI"})


def test_kafka_sink_really_authenticates_with_sasl(broker, monkeypatch: pytest.MonkeyPatch) -> None:
    """The mock broker speaks no SASL: a SASL sink must fail where a plaintext one succeeds."""
    from mushrooms.tool.config import load_config
    from mushrooms.daemon.wiring import make_sink
    import dataclasses

    topic = f"sasl-{time.time_ns()}"
    broker.ensure_topic(topic)
    base = load_config(None)
    plain = dataclasses.replace(base, outbound=dataclasses.replace(
        base.outbound, sink="kafka", bootstrap=broker.bootstrap, topic=topic, delivery_timeout_s=20))
    sink = make_sink(plain.outbound)
    sink.publish({"type": "withdrawal", "superevent_id": "S1"})
    sink.close()
    monkeypatch.setenv("MUSHROOMS_OUTBOUND_PASSWORD", "secret")
    monkeypatch.delenv("CREDENTIALS_DIRECTORY", raising=False)
    sasl = dataclasses.replace(plain, outbound=dataclasses.replace(
        plain.outbound, security_protocol="sasl_plaintext", sasl_mechanism="PLAIN", sasl_username="u",
        delivery_timeout_s=3))
    sink = make_sink(sasl.outbound)
    with pytest.raises(PublishError):
        sink.publish({"type": "withdrawal", "superevent_id": "S2"})


@pytest.mark.parametrize("assignment", ["manual", "group"])
def test_consumer_reads_a_1mb_notice_and_resumes_after_commit(broker, assignment: str) -> None:
    topic = f"in-{assignment}-{time.time_ns()}"
    group = f"g-{time.time_ns()}"
    broker.ensure_topic(topic)
    raw = notice_bytes("MS181101ab-preliminary.json")
    broker.produce(topic, raw, key=b"k")  # one key: one partition, so the order is fixed
    broker.produce(topic, b"second", key=b"k")
    cfg = KafkaConfig(topics=(topic,), group_id=group, bootstrap=broker.bootstrap, assignment=assignment,
                      session_timeout_s=6.0)
    c = NoticeConsumer(cfg)
    got = []
    end = time.monotonic() + 60
    while len(got) < 2 and time.monotonic() < end:
        r = c.poll(0.5)
        if r is not None:
            got.append(r)
    assert [len(r.value) for r in got] == [len(raw), len(b"second")]
    assert got[0].origin.startswith(f"kafka:{topic}:")
    c.commit(got[0])  # only the first one is committed
    c.close()
    c = NoticeConsumer(cfg)
    again = None
    end = time.monotonic() + 60
    while again is None and time.monotonic() < end:
        again = c.poll(0.5)
    c.close()
    assert again is not None and again.value == b"second"


# ---------------------------------------------------------------- systemd unit
def test_systemd_unit_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    tool = shutil.which("systemd-analyze")
    if tool is None:
        pytest.skip("systemd-analyze is not installed here (apt-get install systemd provides it)")
    unit = (REPO / "systemd" / "mushrooms.service").read_text()
    for key in ("Type=notify", "WatchdogSec=", "Restart=on-failure", "StateDirectory=mushrooms",
                "LoadCredential=gcn_client_secret:", "NoNewPrivileges=yes", "ProtectSystem=strict",
                "PrivateTmp=yes"):
        assert key in unit
    # verify checks that ExecStart exists: point it at this checkout's script
    exe = Path(shutil.which("mushrooms", path=str(Path(os.sys.executable).parent)) or "")
    assert exe.is_file()
    local = tmp_path / "mushrooms.service"
    local.write_text(unit.replace("/opt/mushrooms/venv/bin/mushrooms", str(exe)))
    r = subprocess.run([tool, "verify", str(local)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "mushrooms.service" not in r.stderr, r.stderr


def test_command_line_overrides_the_config_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import argparse

    from mushrooms.tool.overrides import effective_config

    cfg = tmp_path / "config.toml"
    cfg.write_text('[outbound]\nsink = "kafka"\ntopic = "plans"\n[kafka]\ntopics = ["igwn.gwalert"]\n')
    args = argparse.Namespace(config=str(cfg), bootstrap="127.0.0.1:9092", outbox=None, state="s.sqlite",
                              allow_mock=True)
    c = effective_config(args)
    assert (c.kafka.bootstrap, c.outbound.sink, c.outbound.bootstrap) == ("127.0.0.1:9092", "kafka", "127.0.0.1:9092")
    assert c.daemon.state_path == "s.sqlite" and c.policy.allow_mock is True
    args.outbox = str(tmp_path / "out")
    c = effective_config(args)
    assert (c.outbound.sink, c.outbound.directory) == ("directory", str(tmp_path / "out"))
    # credentials are never read from the config file: GCN mode without them is refused
    from mushrooms.tool.config import Config

    with pytest.raises(ValueError, match="unknown"):
        Config.from_mapping({"kafka": {"client_secret": "x"}})
    for name in ("GCN_CLIENT_ID", "GCN_CLIENT_SECRET", "CREDENTIALS_DIRECTORY"):
        monkeypatch.delenv(name, raising=False)
    with pytest.raises(CredentialsError, match="GCN_CLIENT_ID"):
        NoticeConsumer(KafkaConfig())
