"""``mushrooms trigger`` with a running daemon (trigger file + SIGUSR1) and
without one (the command does the job itself); SIGHUP and SIGTERM."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from daemon_helpers import REPO, Daemon, notice_path, notify_listener, write_config

FITS = REPO / "mushrooms" / "scheduler_core" / "data" / "MS181101ab_bayestar.multiorder.fits"


def trigger(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", "trigger", *args], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)


def outbox_plans(outbox: Path) -> list[dict]:
    docs = [json.loads(p.read_text()) for p in sorted(outbox.glob("*.json"))] if outbox.is_dir() else []
    return [d for d in docs if d.get("type") == "plan"]


def wait_plans(outbox: Path, n: int, daemon: Daemon, timeout_s: float = 240) -> list[dict]:
    end = time.monotonic() + timeout_s
    while len(outbox_plans(outbox)) < n:
        daemon.alive()
        assert time.monotonic() < end, f"no plan in {outbox}:\n{daemon.text()[-3000:]}"
        time.sleep(0.2)
    return outbox_plans(outbox)


def test_trigger_without_a_daemon_does_the_job_itself(tmp_path: Path) -> None:
    cfg = write_config(tmp_path / "config.toml", "unused", "unused", "unused")
    state, outbox = tmp_path / "state.sqlite", tmp_path / "outbox"
    common = ["--config", str(cfg), "--state", str(state), "--outbox", str(outbox)]

    r = trigger(tmp_path, str(notice_path("MS181101ab-preliminary.json")), *common)
    assert r.returncode == 0, r.stderr
    assert "no daemon running" in r.stdout and "1 job(s) run here" in r.stdout
    (first,) = outbox_plans(outbox)
    assert first["event"]["superevent_id"] == "MS181101ab" and first["observations"]

    # a known superevent id: planned again from now, superseding the first plan
    r = trigger(tmp_path, "MS181101ab", *common)
    assert r.returncode == 0, r.stderr
    plans = {p["plan_id"]: p for p in outbox_plans(outbox)}
    assert len(plans) == 2
    (second,) = [p for p in plans.values() if p["plan_id"] != first["plan_id"]]
    assert second["supersedes"] == first["plan_id"]

    # a bare sky map
    r = trigger(tmp_path, str(FITS), *common)
    assert r.returncode == 0, r.stderr
    bare = [p for p in outbox_plans(outbox) if p["event"]["superevent_id"] is None]
    assert len(bare) == 1 and bare[0]["observations"]

    # an unknown superevent and a missing file are input errors (exit 2, one line)
    r = trigger(tmp_path, "S991231zz", *common)
    assert r.returncode == 2 and "S991231zz" in r.stderr and "Traceback" not in r.stderr
    r = trigger(tmp_path, str(tmp_path / "missing.json"), *common)
    assert r.returncode == 2


def test_trigger_hands_work_to_the_running_daemon_and_signals(broker, daemons, tmp_path: Path) -> None:
    topic = f"quiet-{time.time_ns()}"
    broker.ensure_topic(topic)
    cfg = write_config(tmp_path / "config.toml", topic, "unused", f"g-{time.time_ns()}")
    state, outbox = tmp_path / "state.sqlite", tmp_path / "outbox"
    notify, seen = notify_listener(tmp_path / "notify.sock")  # stands in for systemd
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state),
                          "--outbox", str(outbox)],
               env={"NOTIFY_SOCKET": str(tmp_path / "notify.sock"), "WATCHDOG_USEC": "2000000"})
    daemons.append(d)
    d.wait_log("event=service_ready", 60)
    end = time.monotonic() + 30
    while b"WATCHDOG=1" not in seen and time.monotonic() < end:
        time.sleep(0.1)
    assert seen[0].startswith(b"READY=1\n") and b"WATCHDOG=1" in seen, seen
    assert (tmp_path / "mushrooms.pid").read_text().strip() == str(d.proc.pid)

    r = trigger(tmp_path, str(notice_path("MS181101ab-preliminary.json")), "--config", str(cfg),
                "--state", str(state))
    assert r.returncode == 0, r.stderr
    assert f"handed to the daemon (pid {d.proc.pid}): plan (" in r.stdout  # the first plan's real outcome
    (plan,) = wait_plans(outbox, 1, d)
    assert plan["event"]["superevent_id"] == "MS181101ab"
    assert "event=trigger file=" in d.text() and "kind=notice" in d.text()
    assert list((tmp_path / "mushrooms-triggers").iterdir()) == []

    # the answer is truthful: an unknown superevent and a map the planner refuses are errors
    r = trigger(tmp_path, "S999999zz", "--config", str(cfg), "--state", str(state))
    assert r.returncode == 2 and "rejected" in r.stderr and "S999999zz" in r.stderr, (r.stdout, r.stderr)
    bad = tmp_path / "bad.fits"
    bad.write_bytes(b"SIMPLE  =                    T" + b" " * 50 + b"END".ljust(2880 - 80))
    r = trigger(tmp_path, str(bad), "--config", str(cfg), "--state", str(state))
    assert r.returncode == 2 and "rejected" in r.stderr, (r.stdout, r.stderr)
    assert list((tmp_path / "mushrooms-triggers").iterdir()) == []  # answers consumed

    # a second daemon on the same state refuses to start
    other = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)])
    assert other.proc.wait(60) == 1
    assert "another mushrooms daemon runs" in other.text()

    # SIGHUP reloads the configuration (here: a new heartbeat interval)
    cfg.write_text(cfg.read_text().replace("heartbeat_s = 2", "heartbeat_s = 3"))
    d.proc.send_signal(signal.SIGHUP)
    d.wait_log("event=config_reloaded", 30)
    # a broken file is refused and the running configuration kept
    good = cfg.read_text()
    cfg.write_text(good + "\n[nonsense]\n")
    d.proc.send_signal(signal.SIGHUP)
    d.wait_log("event=reload_failed", 30)
    cfg.write_text(good)

    # SIGTERM: clean stop, pid file removed
    assert d.stop(signal.SIGTERM) == 0
    text = d.text()
    assert "event=service_stopped unfinished_jobs=no" in text
    assert not (tmp_path / "mushrooms.pid").exists()
    time.sleep(0.5)
    notify.close()
    assert b"RELOADING=1" in seen and b"STOPPING=1" in seen and seen.count(b"WATCHDOG=1") >= 1, seen


class RecordingConsole:
    """A TriggerConsole that keeps what it was told, by kind."""

    def __init__(self) -> None:
        self.said: list[tuple[str, str]] = []

    def result(self, text: str) -> None:
        self.said.append(("result", text))

    def note(self, text: str) -> None:
        self.said.append(("note", text))

    def warning(self, text: str) -> None:
        self.said.append(("warning", text))

    def error(self, text: str) -> None:
        self.said.append(("error", text))


def test_run_trigger_is_a_library_call_that_prints_nothing(tmp_path: Path, capsys) -> None:
    # the daemon layer tells its console; only the tool prints (mushrooms trigger's PrintConsole)
    from mushrooms.daemon.settings import resolve_paths
    from mushrooms.daemon.intake.trigger import classify
    from mushrooms.daemon.intake.trigger_command import run_trigger
    from mushrooms.tool.config import load_config
    from mushrooms.tool.overrides import override_config

    cfg = write_config(tmp_path / "config.toml", "unused", "unused", "unused")
    config = override_config(load_config(str(cfg)), outbox=str(tmp_path / "outbox"),
                             state=str(tmp_path / "state.sqlite"))
    paths = resolve_paths(config.daemon)
    console = RecordingConsole()
    kind, payload = classify(str(notice_path("MS181101ab-preliminary.json")))
    assert run_trigger("prelim", kind, payload, config, paths, console=console) == 0
    kinds = [k for k, _ in console.said]
    assert kinds == ["note", "result"], console.said
    assert "no daemon running: planning here" in console.said[0][1]
    assert "1 job(s) run here" in console.said[1][1] and outbox_plans(tmp_path / "outbox")

    refused = RecordingConsole()
    kind, payload = classify("S991231zz")
    assert run_trigger("S991231zz", kind, payload, config, paths, console=refused) == 2
    assert refused.said[-1][0] == "error" and "S991231zz" in refused.said[-1][1]
    out = capsys.readouterr()
    assert out.out == "" and "mushrooms trigger" not in out.err
