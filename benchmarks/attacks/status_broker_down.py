"""Issue 52, finding 10: ``mushrooms status`` says the input broker is down, with the metrics listener off.

The real daemon (``mushrooms run``, default ``[daemon] metrics_address = ""``: no listener) is
started against a loopback port where nothing listens (as with a firewall, or GCN down; wrong
credentials end the same way, librdkafka's ``_AUTHENTICATION`` error), then ``mushrooms status``
is run on its state file; then the daemon is restarted on the same state file against
librdkafka's mock cluster, and ``status`` is run again.

    python benchmarks/attacks/status_broker_down.py [--code DIR]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "daemon"))

from broker_down_setup import BROKER_DOWN_CONFIG, closed_port, run_status  # noqa: E402

CONFIG = BROKER_DOWN_CONFIG.format(group="status-broker-down")


def wait_for(log: Path, needle: str, count: int = 1, timeout_s: float = 180.0) -> None:
    end = time.monotonic() + timeout_s
    while log.read_text(errors="replace").count(needle) < count:
        if time.monotonic() > end:
            raise SystemExit(f"{needle!r} not seen in {log}")
        time.sleep(0.2)


def daemon(tmp: Path, code: str, bootstrap: str, name: str) -> tuple[subprocess.Popen, Path]:
    log = tmp / f"{name}.log"
    env = {**os.environ, "PYTHONPATH": code}
    proc = subprocess.Popen([sys.executable, "-m", "mushrooms.cli", "run", "--config", str(tmp / "config.toml"),
                             "--bootstrap", bootstrap, "--state", str(tmp / "state.sqlite"), "--outbox",
                             str(tmp / "outbox")], cwd=tmp, env=env, stdout=open(log, "wb"), stderr=subprocess.STDOUT)
    return proc, log


def status(tmp: Path, code: str) -> None:
    out = run_status(tmp / "config.toml", tmp / "state.sqlite", tmp, code)
    print("$ mushrooms status --state state.sqlite")
    print(out.stdout.rstrip())
    print(f"[exit {out.returncode}]\n")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--code", default=str(REPO), help="import mushrooms from this directory")
    code = str(Path(p.parse_args().code).resolve())
    sys.path.insert(0, code)
    from mushrooms.tool.loopback_broker import LoopbackBroker

    print(f"code: {code}\nload: {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1/5/15 min)\n")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        (tmp / "config.toml").write_text(CONFIG)
        dead = f"127.0.0.1:{closed_port()}"
        print(f"## the daemon against {dead} (nothing listens), no metrics listener\n")
        proc, log = daemon(tmp, code, dead, "down")
        wait_for(log, "event=broker_unreachable")
        beats = log.read_text().count("event=heartbeat")
        wait_for(log, "event=heartbeat", beats + 2)
        print("daemon log: " + next(ln for ln in log.read_text().splitlines() if "broker_unreachable" in ln)[:220])
        print(f"metrics listener: {'on' if 'metrics_listening' in log.read_text() else 'off'}\n")
        status(tmp, code)
        proc.terminate()
        proc.wait(60)
        with LoopbackBroker() as broker:
            broker.ensure_topic("igwn.gwalert")
            print(f"## restarted on the same state file against the mock cluster {broker.bootstrap}\n")
            proc, log = daemon(tmp, code, broker.bootstrap, "up")
            wait_for(log, "event=broker_reachable")
            beats = log.read_text().count("event=heartbeat")
            wait_for(log, "event=heartbeat", beats + 2)
            status(tmp, code)
            proc.terminate()
            proc.wait(60)
    return 0


if __name__ == "__main__":
    sys.exit(main())
