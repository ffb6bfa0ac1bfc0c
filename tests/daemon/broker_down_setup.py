"""The daemon against a broker nobody answers, and ``mushrooms status`` on its state file (issue 52, finding 10).

Shared by ``tests/daemon/test_status_broker.py`` and
``benchmarks/attacks/status_broker_down.py``: the daemon's configuration (the
greedy scheduler at nside 64, a heartbeat every second, the metrics listener
off by default), a loopback port nothing listens on, and ``mushrooms status``
run as an operator runs it.  Standard library only (the benchmark may import
``mushrooms`` from another tree, ``--code``).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

#: The daemon's config.toml; ``{group}``: its Kafka consumer group.
BROKER_DOWN_CONFIG = """
[scheduler]
solver = "greedy"
nside = 64

[daemon]
heartbeat_s = 1

[kafka]
topics = ["igwn.gwalert"]
group_id = "{group}"
assignment = "group"
poll_timeout_s = 0.5
"""


def closed_port() -> int:
    """A loopback port nothing listens on (bound, never listening: connections are refused)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def run_status(cfg: Path, state: Path, cwd: Path, code: str | None = None) -> subprocess.CompletedProcess:
    """``mushrooms status --config cfg --state state`` in a new process (``code``: import mushrooms from there)."""
    env = {**os.environ, "PYTHONPATH": code} if code else None
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", "status", "--config", str(cfg), "--state",
                           str(state)], capture_output=True, text=True, timeout=120, cwd=cwd, env=env)
