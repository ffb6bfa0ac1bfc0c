"""A warm-up plan that fails makes the service not ready, with the reason, until a plan succeeds.

The warm-up's throw-away plan runs the first stage of every job (the sky map
read, the problem, the fast scheduler, the checker).  It once failed with a
mere WARNING while ``/readyz`` was green and every job failed the same way
(``[scheduler] slew = 1``, now refused at load).  Here the bundled demo map
the warm-up plans is not FITS (a broken install): the real warm-up, the
readiness check of the service, the re-warm timer that tries the plan again,
and the real daemon (through the test gate) whose ``/readyz`` says why it is
not ready while it still plans the alerts it receives.
"""

from __future__ import annotations

import json
import logging
import signal
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from mushrooms.daemon.ops.health import service_checks
from mushrooms.daemon.planning.warm import SkyCache, warm_up
from mushrooms.daemon.timers import Timers
from mushrooms.scheduler_core import PlanningConfig

from daemon_helpers import Daemon, notice_bytes, notify_listener, write_config

CFG = PlanningConfig(nside=64, time_step_s=600.0)


def _service(cache: SkyCache, tmp_path: Path) -> SimpleNamespace:
    return SimpleNamespace(phase="running", sky_cache=cache, paths=SimpleNamespace(state=tmp_path / "s.sqlite"),
                           config=SimpleNamespace(scheduler=CFG), submit_drain=None)


def _break_the_demo_map(monkeypatch, tmp_path: Path) -> None:
    """The bundled map the warm-up plans is not FITS (a broken install): its plan fails for real."""
    import mushrooms.bundled

    broken = tmp_path / "broken-demo-map.fits"
    broken.write_bytes(b"this is not a FITS file\n" * 200)
    monkeypatch.setattr(mushrooms.bundled, "demo_skymap_path", lambda: str(broken))


def test_a_failing_warm_up_plan_is_an_error_and_the_service_is_not_ready_until_a_plan_succeeds(
        tmp_path, caplog, monkeypatch):
    caplog.set_level(logging.INFO, logger="mushrooms.daemon")
    _break_the_demo_map(monkeypatch, tmp_path)
    cache = SkyCache()
    warm_up(cache, CFG)
    errors = [r for r in caplog.records if r.getMessage().startswith("event=warm_up_plan_failed")]
    assert [r.levelno for r in errors] == [logging.ERROR], [r.getMessage() for r in caplog.records]
    assert cache.plan_failure is not None and "broken-demo-map.fits" in cache.plan_failure

    service = _service(cache, tmp_path)
    ok, detail = service_checks(service)["warm_up"]()
    assert ok is False
    assert "warm-up plan failed" in detail and "broken-demo-map.fits" in detail, detail

    # the re-warm timer tries the plan again: still failing, still not ready
    Timers(service).rewarm()
    assert service_checks(service)["warm_up"]()[0] is False
    # once the plan succeeds (here: the install repaired), the service is ready
    caplog.clear()
    monkeypatch.undo()
    Timers(service).rewarm()
    assert cache.plan_failure is None
    assert service_checks(service)["warm_up"]() == (True, "done")
    assert any(r.getMessage().startswith("event=warm_up_plan_recovered") for r in caplog.records)


def test_a_warm_up_plan_that_succeeds_leaves_the_service_ready(tmp_path):
    cache = SkyCache()
    warm_up(cache, CFG)
    assert cache.plan_failure is None
    assert service_checks(_service(cache, tmp_path))["warm_up"]() == (True, "done")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _readyz(port: int) -> tuple[int, dict]:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/readyz", timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def test_the_daemon_whose_warm_up_plan_fails_is_not_ready_says_why_and_still_plans(broker, daemons, tmp_path):
    # not refused at start: the failure may concern the warm-up's own map only (here: a broken
    # install's demo map), and a running service still stores every notice and tries every job
    topic, out, group = broker.fresh_topics()
    port = _free_port()
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    cfg.write_text(cfg.read_text().replace("[daemon]\n", f'[daemon]\nmetrics_address = "127.0.0.1:{port}"\n'))
    gate = tmp_path / "gate"
    gate.mkdir()
    (gate / "fail-warm").touch()
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap,
                          "--state", str(tmp_path / "state.sqlite")], gate=gate)
    daemons.append(d)
    d.wait_log("event=consuming", 180)
    text = d.text()
    assert " ERROR mushrooms.daemon: event=warm_up_plan_failed " in text, text[-3000:]
    end = time.monotonic() + 60
    while True:  # partitions and the broker turn green; the warm-up stays red
        code, body = _readyz(port)
        if body["failed"] == ["warm_up"] or time.monotonic() > end:
            break
        time.sleep(0.2)
    assert code == 503 and body["failed"] == ["warm_up"], body
    assert "warm-up plan failed" in body["checks"]["warm_up"]["detail"], body

    reader = broker.reader(out, f"{group}-reader")
    try:
        broker.produce(topic, notice_bytes("MS181101ab-preliminary.json", "MS991231w"))
        reader.wait_for(lambda ms: any(m.get("type") in ("plan", "not_observable") for m in ms), 180, d.alive)
    finally:
        reader.close()
    assert d.stop() == 0


def _status(tmp_path: Path, state: Path) -> "subprocess.CompletedProcess":
    import os
    import subprocess
    import sys

    from daemon_helpers import REPO

    env = {k: v for k, v in os.environ.items() if k != "MUSHROOMS_CONFIG"}
    env["PYTHONPATH"] = str(REPO)
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", "--log-level", "WARNING", "status", "--state",
                           str(state)], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)


def _wait(what: str, ok, d: Daemon, timeout_s: float = 120.0) -> None:
    end = time.monotonic() + timeout_s  # a hang guard only
    while not ok():
        d.alive()
        assert time.monotonic() < end, f"{what}:\n{d.text()[-3000:]}"
        time.sleep(0.2)


def _failing_daemon(broker, daemons, tmp_path: Path, systemd: bool = True
                    ) -> tuple[Daemon, Path, Path, list[bytes], Any]:
    """A daemon whose warm-up plan fails (a broken install), told to a stand-in for systemd when ``systemd``."""
    topic, out, group = broker.fresh_topics()
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    gate, state = tmp_path / "gate", tmp_path / "state.sqlite"
    gate.mkdir()
    (gate / "fail-warm").touch()
    notify, seen = notify_listener(tmp_path / "notify.sock") if systemd else (None, [])
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)], gate=gate,
               env={"NOTIFY_SOCKET": str(tmp_path / "notify.sock")} if systemd else None)
    daemons.append(d)
    d.wait_log("event=service_ready", 180)
    assert "event=warm_up_plan_failed" in d.text()
    return d, gate, state, seen, notify


def test_status_and_systemd_say_a_failed_warm_up_plan_without_the_metrics_listener(broker, daemons, tmp_path):
    """Only the ERROR line said it: ``status`` exited 0, systemd's STATUS line said "consuming ..."."""
    d, gate, state, seen, notify = _failing_daemon(broker, daemons, tmp_path)
    try:
        _wait("a STATUS line that says the warm-up plan failed",
              lambda: any(b"STATUS=" in m and b"warm-up plan failed" in m for m in seen), d)
        r = _status(tmp_path, state)
        assert r.returncode == 1, r.stdout + r.stderr
        assert "warm-up plan: FAILED since" in r.stdout and "broken-demo-map.fits" in r.stdout, r.stdout
        assert "the warm-up plan failed" in r.stdout.split("NEEDS ATTENTION", 1)[1], r.stdout
        # repaired and reloaded: cleared in the state file and in systemd's line (item 6 runs it at the reload)
        (gate / "fail-warm").unlink()
        d.proc.send_signal(signal.SIGHUP)
        d.wait_log("event=warm_up_plan_recovered", 120)
        _wait("status clear of the warm-up plan", lambda: _status(tmp_path, state).returncode == 0, d)
        r = _status(tmp_path, state)
        assert "warm-up plan: ok since" in r.stdout and "FAILED" not in r.stdout, r.stdout
        n = len(seen)
        _wait("a STATUS line after the recovery", lambda: any(b"STATUS=" in m for m in seen[n:]), d)
        assert not any(b"warm-up plan failed" in m for m in seen[n:] if b"STATUS=" in m), seen[n:]
    finally:
        notify.close()
    assert d.stop() == 0


def test_a_reload_runs_the_warm_up_plan_again_so_a_repaired_install_is_ready_at_once(broker, daemons, tmp_path):
    """After a broken install was repaired, a SIGHUP left readiness red until the next re-warm (up to 30 min)."""
    d, gate, state, _, _ = _failing_daemon(broker, daemons, tmp_path, systemd=False)
    (gate / "fail-warm").unlink()
    d.proc.send_signal(signal.SIGHUP)
    d.wait_log("event=config_reloaded", 60)
    # the re-warm timer runs every 30 min: a recovery within the hang guard is the reload's own warm-up plan
    d.wait_log("event=warm_up_plan_recovered", 120)
    text = d.text()
    reloaded = text.index("event=config_reloaded")
    assert text.index("event=warm_up_plan_recovered") > reloaded
    assert d.stop() == 0
