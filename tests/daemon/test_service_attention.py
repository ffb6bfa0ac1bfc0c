"""The service under attack from its own operators' side: the metrics listener, readiness, ``mushrooms status``.

A plan that did not reach the telescope must be impossible to miss:
``/readyz`` (the ``submission`` check), ``mushrooms status`` (exit 1 on a
submission pending longer than ``[submit] max_pending_s``), the gauge
``mushrooms_submission_oldest_pending_age_seconds`` and its alert rule.
Real stores, real listeners on loopback, the real CLI.
"""

from __future__ import annotations

import json
import logging
import socket
import sqlite3
import threading
import time
import urllib.request
from pathlib import Path

import pytest

from mushrooms.daemon.ops.health import HealthServer
from mushrooms.daemon.drain import OutboxDrain
from mushrooms.daemon.ops.metrics import ServiceMetrics
from mushrooms.daemon.state.store import Store
from test_submissions import SID, World, _config, kowalski, server  # noqa: F401 (fixtures)

OPS = Path(__file__).resolve().parents[2] / "docs" / "operations.md"


def _listener(tmp_path: Path, **kw) -> HealthServer:
    Store(tmp_path / "state.sqlite").close()
    metrics = ServiceMetrics("0", tmp_path / "state.sqlite")
    return HealthServer("127.0.0.1", 0, metrics, lambda: (True, {}), **kw).start()


def test_idle_metrics_connections_take_a_bounded_number_of_threads(tmp_path) -> None:
    listener = _listener(tmp_path, max_connections=16)
    socks = []
    try:
        before = threading.active_count()
        for _ in range(50):  # idle: connected, nothing sent (300 of them in benchmarks/metrics_idle_connections.py)
            socks.append(socket.create_connection(listener.address, timeout=5))
        time.sleep(0.3)
        grown = threading.active_count() - before
        assert grown <= 20, f"{grown} threads for 50 idle connections"
        for s in socks:
            s.close()
        socks = []
        with urllib.request.urlopen(f"http://{listener.address[0]}:{listener.address[1]}/metrics", timeout=10) as r:
            assert r.status == 200 and b"mushrooms_build_info" in r.read()
    finally:
        for s in socks:
            s.close()
        listener.close()


def test_an_idle_metrics_connection_is_closed_after_its_timeout(tmp_path) -> None:
    listener = _listener(tmp_path, connection_timeout_s=0.5)
    try:
        s = socket.create_connection(listener.address)
        s.settimeout(10)
        s.sendall(b"GET /metr")  # never finished
        assert s.recv(100) == b""  # the server hung up
        s.close()
    finally:
        listener.close()


def _pending_world(tmp_path: Path, age_s: float) -> World:
    """A store with one plan whose submission waits (Kowalski unreachable), ``age_s`` old."""
    dead = socket.socket()
    dead.bind(("127.0.0.1", 0))
    url = f"http://127.0.0.1:{dead.getsockname()[1]}"  # bound, never listening: connection refused
    w = World(tmp_path / "state.sqlite", _config(url))
    w.notice("MS181101ab-preliminary.json")
    assert w.submitter.step() == 1
    past = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(time.time() - age_s)) + ".000+00:00"
    with w.store.transaction() as c:
        c.execute("UPDATE submissions SET created_at=?", (past,))
    dead.close()
    return w


def test_status_exits_1_on_a_submission_pending_longer_than_the_configured_age(tmp_path, capsys) -> None:
    from mushrooms.cli import main

    w = _pending_world(tmp_path, 3600.0)
    (name,) = [r[0] for r in w.store.connection().execute("SELECT queue_name FROM submissions")]
    w.store.close()
    cfg = tmp_path / "c.toml"
    cfg.write_text("[submit]\nmax_pending_s = 600\n")
    capsys.readouterr()
    assert main(["status", "--config", str(cfg), "--state", str(tmp_path / "state.sqlite")]) == 1
    out = capsys.readouterr().out
    assert "NEEDS ATTENTION" in out and name.startswith(f"ToO_GW_{SID}_") and name in out and "pending" in out
    cfg.write_text("[submit]\nmax_pending_s = 7200\n")
    main(["status", "--config", str(cfg), "--state", str(tmp_path / "state.sqlite")])
    assert "pending" not in capsys.readouterr().out.split("nothing needs attention")[-1]


def test_the_oldest_pending_submission_is_a_gauge(tmp_path) -> None:
    w = _pending_world(tmp_path, 120.0)
    try:
        text = ServiceMetrics("0", w.path).render().decode()
        (line,) = [ln for ln in text.splitlines() if ln.startswith("mushrooms_submission_oldest_pending_age_seconds ")]
        assert 100.0 < float(line.split()[1]) < 1000.0
    finally:
        w.store.close()


def test_readiness_fails_while_submissions_fail_or_wait_too_long(tmp_path) -> None:
    from mushrooms.daemon.ops.health import submission_check

    w = _pending_world(tmp_path, 3600.0)
    fail = threading.Event()

    def flush() -> int:
        if fail.is_set():
            raise ConnectionError("Kowalski unreachable")
        return 0

    drain = OutboxDrain(flush, initial_s=60.0, max_s=60.0, name="submit")
    (name,) = [r[0] for r in w.store.connection().execute("SELECT queue_name FROM submissions")]
    try:
        ok, detail = submission_check(w.path, drain, max_pending_s=600.0)()
        assert not ok and name.startswith(f"ToO_GW_{SID}_") and name in detail and "pending" in detail
        ok, detail = submission_check(w.path, drain, max_pending_s=7200.0)()
        assert ok, detail
        fail.set()
        drain.kick()
        for _ in range(100):
            if drain.retry_scheduled:
                break
            time.sleep(0.05)
        ok, detail = submission_check(w.path, drain, max_pending_s=7200.0)()
        assert not ok and "failing" in detail
    finally:
        drain.close()
        w.store.close()


def test_the_service_registers_the_submission_readiness_check(tmp_path) -> None:
    from types import SimpleNamespace

    from mushrooms.daemon.ops.health import service_checks

    Store(tmp_path / "state.sqlite").close()
    service = SimpleNamespace(paths=SimpleNamespace(state=tmp_path / "state.sqlite"), submit_drain=None,
                              config=SimpleNamespace(submit=_config("http://127.0.0.1:9").submit))
    assert "submission" not in service_checks(service)
    drain = OutboxDrain(lambda: 0, name="submit")
    try:
        service.submit_drain = drain
        assert "submission" in service_checks(service)
    finally:
        drain.close()


def test_status_without_state_reads_the_configured_state_file(tmp_path, capsys) -> None:
    from mushrooms.cli import main

    Store(tmp_path / "here.sqlite").close()
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'[daemon]\nstate_path = "{tmp_path / "here.sqlite"}"\n')
    assert main(["status", "--config", str(cfg)]) == 0
    assert "nothing needs attention" in capsys.readouterr().out


def test_status_on_an_older_schema_says_which_and_what_to_do(tmp_path, capsys) -> None:
    from mushrooms.cli import main

    path = tmp_path / "old.sqlite"
    Store(path).close()
    conn = sqlite3.connect(path)
    conn.execute("ALTER TABLE plans DROP COLUMN revision")
    conn.execute("PRAGMA user_version=1")
    conn.commit()
    conn.close()
    assert main(["status", "--state", str(path)]) == 2
    err = capsys.readouterr().err
    assert "schema 1" in err and "no such column" not in err and "mushrooms run" in err


def test_status_on_a_busy_state_file_says_busy(tmp_path, capsys) -> None:
    from mushrooms.cli import main

    path = tmp_path / "busy.sqlite"
    Store(path).close()
    holder = sqlite3.connect(path, isolation_level=None)
    holder.execute("PRAGMA locking_mode=EXCLUSIVE")
    holder.execute("BEGIN EXCLUSIVE")
    holder.execute("INSERT INTO incidents(kind, detail, created_at) VALUES ('x', '{}', '2026-01-01T00:00:00Z')")
    try:
        code = main(["status", "--state", str(path), "--busy-timeout", "0.2"])
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    err = capsys.readouterr().err
    assert code == 1 and "busy" in err and "not a readable" not in err


def test_published_plans_are_not_logged_as_unpublished(tmp_path, caplog) -> None:
    from mushrooms.daemon.intake.pipeline import NoticePipeline
    from mushrooms.daemon.sinks import MemorySink
    from daemon_helpers import notice_bytes

    store = Store(tmp_path / "state.sqlite")
    try:
        pipeline = NoticePipeline.from_config(_config("http://127.0.0.1:9"), store, MemorySink(),
                                              on_outbox=lambda: None)  # the daemon's drain publishes
        with caplog.at_level(logging.INFO, logger="mushrooms"):
            pipeline.handle(notice_bytes("MS181101ab-preliminary.json"), "test")
        lines = [r.getMessage() for r in caplog.records if "decision=" in r.getMessage() and "plan_id=" in r.getMessage()]
        assert lines and all("published=False" not in ln for ln in lines), lines
        assert all("published=queued" in ln for ln in lines if "published=" in ln)
    finally:
        store.close()


def test_the_operations_doc_names_every_submission_series_and_alerts_on_a_stuck_one() -> None:
    text = OPS.read_text()
    assert 'mushrooms_published_messages_total{type="submission"}' in text
    assert 'mushrooms_submissions_total{result="pending"}' in text
    assert "(added by the submission feature" not in text
    import re

    import yaml

    rules = yaml.safe_load(re.search(r"```yaml\n(groups:.*?)```", text, re.DOTALL).group(1))["groups"][0]["rules"]
    assert any("mushrooms_submission_oldest_pending_age_seconds" in r["expr"] for r in rules)
    assert "max_pending_s" in text


def test_a_bare_sky_maps_queue_name_is_what_the_plan_format_says() -> None:
    plan_format = (OPS.parent / "design" / "plan-format.md").read_text()
    assert "`ToO_<superevent>`)" not in plan_format
    assert "`ToO_<subprogram>_<plan tag>_<k>` for a\n  bare sky map" in plan_format
