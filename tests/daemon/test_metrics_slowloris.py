"""The metrics/health listener under a slowloris: idle and dripping connections never silence ``/healthz``.

Issue 52 (LOW): 1500 idle connections left ``/healthz`` unanswered and printed
16 raw tracebacks.  Here a few hundred idle sockets on loopback (the 1500 of
the issue: ``benchmarks/attacks/metrics_slowloris.py``), the real listener.
"""

from __future__ import annotations

import json
import logging
import socket
import threading
import time
import urllib.request
from pathlib import Path

from mushrooms.daemon.ops.health import HealthServer
from mushrooms.daemon.ops.metrics import ServiceMetrics
from mushrooms.daemon.state.store import Store

#: Idle connections held open during the test (the issue's scenario has 1500).
IDLE = 300


def _listener(tmp_path: Path, **kw) -> HealthServer:
    Store(tmp_path / "state.sqlite").close()
    metrics = ServiceMetrics("0", tmp_path / "state.sqlite")
    return HealthServer("127.0.0.1", 0, metrics, lambda: (True, {"phase": "running"}), **kw).start()


def _open_idle(address: tuple[str, int], n: int, first_bytes: bytes = b"") -> list[socket.socket]:
    socks = []
    for _ in range(n):
        s = socket.create_connection(address, timeout=5)
        if first_bytes:
            s.sendall(first_bytes)
        socks.append(s)
    return socks


def test_healthz_answers_while_hundreds_of_idle_connections_stay_open(tmp_path) -> None:
    listener = _listener(tmp_path)
    socks: list[socket.socket] = []
    try:
        before = threading.active_count()
        socks = _open_idle(listener.address, IDLE)
        socks += _open_idle(listener.address, 20, b"GET /metr")  # a head that never ends
        time.sleep(0.5)
        host, port = listener.address
        with urllib.request.urlopen(f"http://{host}:{port}/healthz", timeout=30) as r:  # 30 s: a hang guard
            assert r.status == 200 and json.loads(r.read())["alive"] is True
        with urllib.request.urlopen(f"http://{host}:{port}/metrics", timeout=30) as r:
            assert r.status == 200 and b"mushrooms_build_info" in r.read()
        grown = threading.active_count() - before
        assert grown <= 20, f"{grown} threads for {IDLE + 20} idle connections"
    finally:
        for s in socks:
            s.close()
        listener.close()


def test_timed_out_connections_print_no_traceback_and_log_one_line(tmp_path, capfd, caplog) -> None:
    caplog.set_level(logging.INFO, logger="mushrooms.daemon.health")
    listener = _listener(tmp_path, connection_timeout_s=0.5)
    socks: list[socket.socket] = []
    try:
        socks = _open_idle(listener.address, 30) + _open_idle(listener.address, 10, b"GET /heal")
        for s in socks:  # each is hung up on by the server once its time is up (30 s: a hang guard)
            s.settimeout(30)
            try:
                while s.recv(100):
                    pass
            except OSError:
                pass
        host, port = listener.address
        with urllib.request.urlopen(f"http://{host}:{port}/healthz", timeout=30) as r:
            assert r.status == 200
    finally:
        for s in socks:
            s.close()
        listener.close()
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception occurred" not in err, err[:2000]
    lines = [r.getMessage() for r in caplog.records if r.name == "mushrooms.daemon.health"]
    dropped = [ln for ln in lines if "connections_dropped" in ln]
    assert len(dropped) == 1, lines
    assert "timed_out=" in dropped[0]
