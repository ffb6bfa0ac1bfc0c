"""A stop asked for during the start-up's warm-up ends the start at the warm-up's next step.

systemd's stop (SIGTERM) must take effect at any point of the start, not
only once the Kafka consumer is up: the real daemon on the mock broker, held
at the start of its warm-up by the test gate (``gated_run.py``), gets
SIGTERM there; once let go, the warm-up stops before its first step and the
daemon stops cleanly without ever opening its consumer.  In process, the
real warm-up with a stop that comes after its first step stops before the
second.
"""

from __future__ import annotations

import logging
import signal
import time
from pathlib import Path

from mushrooms.daemon.planning.warm import SkyCache, warm_up
from mushrooms.scheduler_core import PlanningConfig

from daemon_helpers import Daemon, write_config

CFG = PlanningConfig(nside=64, time_step_s=600.0)


def _wait_for(path: Path, d: Daemon, timeout_s: float = 120.0) -> None:
    end = time.monotonic() + timeout_s
    while not path.exists():
        d.alive()
        assert time.monotonic() < end, f"{path.name} never appeared:\n{d.text()[-3000:]}"
        time.sleep(0.05)


def test_sigterm_during_the_warm_up_stops_the_daemon_before_it_consumes(broker, daemons, tmp_path: Path) -> None:
    stamp = time.time_ns()
    topic, out, group = f"gwalert-{stamp}", f"plans-{stamp}", f"mushrooms-{stamp}"
    broker.ensure_topic(topic)
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    gate = tmp_path / "gate"
    gate.mkdir()
    (gate / "hold-warm").touch()
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap,
                          "--state", str(tmp_path / "state.sqlite")], gate=gate)
    daemons.append(d)
    _wait_for(gate / "warming", d)  # the start-up is in its warm-up
    d.proc.send_signal(signal.SIGTERM)
    (gate / "hold-warm").unlink()
    assert d.stop(timeout_s=120.0) == 0
    text = d.text()
    assert "event=warm_up_stopped before=footprints" in text
    assert "event=start_abandoned phase=warming" in text
    assert "event=service_stopped unfinished_jobs=no" in text
    # the warm-up did not complete, and nothing after it started
    for later in ("event=warm_up cache_s", "event=service_starting", "event=consumer_started", "event=service_ready"):
        assert later not in text, later


def test_the_warm_up_stops_at_the_step_after_the_stop(caplog) -> None:
    cache = SkyCache()
    caplog.set_level(logging.INFO, logger="mushrooms.daemon")
    warm_up(cache, CFG, should_stop=lambda: bool(cache._footprints))  # stop once the footprints are in
    assert set(cache._footprints) == {CFG.nside} and cache.misses == 0  # no night's visibility computed
    lines = [r.getMessage() for r in caplog.records]
    assert any(line.startswith("event=warm_up_stopped before=visibility_tonight") for line in lines), lines
    assert not any(line.startswith("event=warm_up ") for line in lines)


def test_without_a_stop_the_warm_up_takes_every_step(caplog) -> None:
    cache = SkyCache()
    caplog.set_level(logging.INFO, logger="mushrooms.daemon")
    warm_up(cache, CFG, should_stop=lambda: False)
    assert set(cache._footprints) == {CFG.nside} and cache.misses >= 1
    lines = [r.getMessage() for r in caplog.records]
    assert any(line.startswith("event=warm_up cache_s=") for line in lines), lines
    assert not any("warm_up_stopped" in line or "warm_up_plan_failed" in line for line in lines), lines
