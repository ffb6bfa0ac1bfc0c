"""What the webhook is told through the real daemon, and first-plan latency with a healthy vs a hanging webhook.

Usage::

    nice -n 5 .venv/bin/python benchmarks/notify_latency.py [--events 5] [--out benchmarks/results/observer]

Runs the real ``mushrooms run`` twice with the default ``[scheduler]``
(nside 256, hybrid, the 14 s optimisation) on the loopback mock Kafka
broker, ``[notify] target = "json"`` and ``[submit] target = "kowalski"``
pointed at a closed port on 127.0.0.1 (Kowalski's stand-in is down):

* ``healthy``: the webhook is a local HTTP server (pytest-httpserver) that
  answers 200 at once; every message it receives is printed;
* ``hanging``: the webhook is a socket that accepts every connection and
  never answers (each POST waits for ``[notify] timeout_s`` = 5 s, the default).

Each run gets the same notices one after the other: live copies of the shared
preliminaries (``mushrooms.tool.live_notice``: created now, the merger its
original lead before), each with a fresh superevent id; the next is sent once
the previous one's plan is final (so the optimiser of one event does not
slow the next).  The latency is the daemon's own, ``event=job_first_plan
... latency_s`` (notice consumed -> revision 1 stored).  The machine is
shared: the load average is printed beside the numbers.
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import statistics
import sys
import tempfile
import threading
import time
from datetime import datetime, timezone
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "daemon"))

from contract_servers import loopback_server  # noqa: E402
from daemon_helpers import Broker, Daemon, notice_path  # noqa: E402

from mushrooms.tool.live_notice import live_copy  # noqa: E402

NOTICES = ["MS181101ab-preliminary.json", "MS230425l-preliminary.json", "MS260605l-preliminary.json"]
HOOK_PATH = "/hook/s3cr3t"

CONFIG = """
[policy]
allow_mock = true

[kafka]
topics = ["{topic}"]
group_id = "{group}"
assignment = "manual"
poll_timeout_s = 0.5

[outbound]
sink = "directory"
directory = "{outbox}"

[notify]
target = "json"

[submit]
target = "kowalski"
url = "http://127.0.0.1:{closed}"
timeout_s = 2.0
retry_initial_s = 5.0
retry_max_s = 60.0
"""


class SilentListener:
    """A TCP socket on 127.0.0.1 that accepts every connection and never reads nor answers."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(64)
        self.port = self.sock.getsockname()[1]
        self.held: list[socket.socket] = []
        self._stop = threading.Event()
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        self.sock.settimeout(0.2)
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            self.held.append(conn)

    def close(self) -> None:
        self._stop.set()
        for c in self.held:
            c.close()
        self.sock.close()


def closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def sid(tag: str, i: int) -> str:
    a = "abcdefghijklmnopqrstuvwxyz"
    return f"MS{datetime.now(timezone.utc):%y%m%d}{tag}{a[i // 26 % 26]}{a[i % 26]}"


def run(broker: Broker, work: Path, label: str, hook_url: str, events: int) -> tuple[list[float], str]:
    """First-plan latencies (s) of ``events`` notices, and the daemon's log."""
    topic = f"gwalert-{label}-{time.time_ns()}"
    broker.ensure_topic(topic)
    cfg = work / f"{label}.toml"
    cfg.write_text(CONFIG.format(topic=topic, group=f"bench-{label}-{time.time_ns()}", outbox=work / f"out-{label}",
                                 closed=closed_port()))
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(work / f"{label}.sqlite")],
               env={"MUSHROOMS_SUBMIT_TOKEN": "bench-token", "MUSHROOMS_NOTIFY_URL": hook_url})
    try:
        d.wait_log("event=service_ready", 600)
        latencies = []
        for i in range(events):
            s = sid(label[0], i)
            notice, _ = live_copy(notice_path(NOTICES[i % len(NOTICES)]).read_bytes(), superevent_id=s)
            broker.produce(topic, notice, key=s.encode())
            text = d.wait_log(f"event=job_first_plan superevent_id={s} ", 300)
            m = re.search(rf"event=job_first_plan superevent_id={s} .*?latency_s=([0-9.]+)", text)
            latencies.append(float(m.group(1)))
            d.wait_log(f"event=job_done superevent_id={s} ", 300)
            print(f"  [{label}] {s}: first plan {latencies[-1]:.3f} s, load {os.getloadavg()[0]:.1f}", flush=True)
        return latencies, d.text()
    finally:
        d.stop()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--events", type=int, default=5)
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "observer")
    args = ap.parse_args()
    broker = Broker()
    server = loopback_server()
    server.expect_request(HOOK_PATH, method="POST").respond_with_data("ok")
    silent = SilentListener()
    lines = [f"# notify_latency.py {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, "
             f"load before {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}", ""]
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for label, url in [("healthy", server.url_for(HOOK_PATH)), ("hanging", f"http://127.0.0.1:{silent.port}"
                                                                             f"{HOOK_PATH}")]:
            load0 = os.getloadavg()[0]
            results[label], text = run(broker, work, label, url, args.events)
            lines.append(f"{label:8s} first-plan latency_s: {' '.join(f'{x:.3f}' for x in results[label])}  "
                         f"median {statistics.median(results[label]):.3f}  (load {load0:.1f} -> "
                         f"{os.getloadavg()[0]:.1f})")
            lines.append(f"         log: notify_sent {text.count('event=notify_sent')}, notify_failed "
                         f"{text.count('event=notify_failed')}, notify_dropped {text.count('event=notify_dropped')}, "
                         f"the webhook's secret path in the log: {'YES' if 's3cr3t' in text else 'no'}")
    ratio = statistics.median(results["hanging"]) / statistics.median(results["healthy"])
    lines += [f"hanging / healthy median: {ratio:.2f}", f"connections the silent webhook held: {len(silent.held)}",
              "", "## what the healthy webhook received (JSON target), in order"]
    import json

    for req, _ in server.log:
        body = json.loads(req.get_data())
        lines.append(f"- [{body.get('event')}] {body.get('text')}")
    silent.close()
    server.stop()
    text = "\n".join(lines)
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "notify_latency.txt").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
