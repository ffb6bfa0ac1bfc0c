"""What the webhook is told through the real daemon, and first-plan latency with a healthy vs a hanging webhook.

Usage::

    nice -n 5 .venv/bin/python benchmarks/speed/notify_latency.py [--events 6] [--out benchmarks/results/loop/observer]

Runs the real ``mushrooms run`` twice, side by side, with the default ``[scheduler]``
(nside 256, hybrid, the 14 s optimisation) on the loopback mock Kafka
broker, ``[notify] target = "json"`` and ``[submit] target = "kowalski"``
pointed at a closed port on 127.0.0.1 (Kowalski's stand-in is down):

* ``healthy``: the webhook is a local HTTP server (pytest-httpserver) that
  answers 200 at once; every message it receives is printed;
* ``hanging``: the webhook is a socket that accepts every connection and
  never answers (each POST waits for ``[notify] timeout_s`` = 5 s, the default).

Both get the same notices, one at a time, the arms alternating (healthy,
hanging, then hanging, healthy, ...: on a shared machine both see the same
load): live copies of the shared preliminaries (``mushrooms.tool.live_notice``:
created now, the merger its original lead before), each with a fresh
superevent id; the next is sent once the previous job is done (so the
optimiser of one event does not slow the next).  The latency is the daemon's own, ``event=job_first_plan
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

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "daemon"))

from contract_servers import loopback_server  # noqa: E402
from daemon_helpers import Broker, Daemon, notice_path  # noqa: E402

from mushrooms.tool.live_notice import live_copy  # noqa: E402

sys.path.insert(0, str(REPO / "benchmarks" / "speed"))
sys.path.insert(0, str(REPO / "benchmarks" / "common"))  # benchmarks/common: the shared helpers
from latency_summary import latency_line, write_summary  # noqa: E402
from submit_latency import CONFIG, NOTICES  # noqa: E402  (policy, loopback input, directory outbox, then {submit})

HOOK_PATH = "/hook/s3cr3t"

#: The daemon's sections after submit_latency.py's (mock broker input, directory outbox): the webhook, and
#: Kowalski's stand-in at a closed port.
NOTIFY_AND_SUBMIT = """
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


class Arm:
    """One daemon, its webhook, its notices."""

    def __init__(self, broker: Broker, work: Path, label: str, hook_url: str) -> None:
        self.broker, self.label = broker, label
        self.tag = {"healthy": "h", "hanging": "g"}[label]  # superevent ids: MS<date><tag><2 letters>
        work = work / label  # a daemon's pid file and trigger directory live beside its state
        work.mkdir()
        self.topic = f"gwalert-{label}-{time.time_ns()}"
        broker.ensure_topic(self.topic)
        cfg = work / f"{label}.toml"
        cfg.write_text(CONFIG.format(topic=self.topic, group=f"bench-{label}-{time.time_ns()}",
                                     outbox=work / f"out-{label}",
                                     submit=NOTIFY_AND_SUBMIT.format(closed=closed_port())))
        self.daemon = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap,
                                    "--state", str(work / f"{label}.sqlite")],
                             env={"MUSHROOMS_SUBMIT_TOKEN": "bench-token", "MUSHROOMS_NOTIFY_URL": hook_url})
        self.latencies: list[float] = []
        self.loads: list[float] = []

    def one(self, i: int) -> None:
        """Send notice ``i`` (a live copy), wait for its first plan and for the end of its job."""
        d = self.daemon
        s = sid(self.tag, i)
        notice, _ = live_copy(notice_path(NOTICES[i % len(NOTICES)]).read_bytes(), superevent_id=s)
        self.loads.append(os.getloadavg()[0])
        self.broker.produce(self.topic, notice, key=s.encode())
        text = d.wait_log(f"event=job_first_plan superevent_id={s} ", 300)
        m = re.search(rf"event=job_first_plan superevent_id={s} .*?latency_s=([0-9.]+)", text)
        self.latencies.append(float(m.group(1)))
        d.wait_log(f"event=job_done superevent_id={s} ", 300)
        print(f"  [{self.label}] {s}: first plan {self.latencies[-1]:.3f} s, load {self.loads[-1]:.1f}", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--events", type=int, default=6)
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "loop" / "observer")
    ap.add_argument("--keep", metavar="DIR", help="keep the daemons' logs and state files in DIR (new)")
    args = ap.parse_args()
    broker = Broker()
    server = loopback_server()
    server.expect_request(HOOK_PATH, method="POST").respond_with_data("ok")
    silent = SilentListener()
    load = os.getloadavg()
    lines = [f"# notify_latency.py {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, "
             f"load before {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}",
             "both daemons run side by side; notices go to one at a time, the arms' order alternating "
             "(healthy, hanging, hanging, healthy, ...), each sent once the previous job is done", ""]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)  # --keep: the daemons' logs and state stay there
        arms = [Arm(broker, work, "healthy", server.url_for(HOOK_PATH)),
                Arm(broker, work, "hanging", f"http://127.0.0.1:{silent.port}{HOOK_PATH}")]
        try:
            for arm in arms:
                arm.daemon.wait_log("event=service_ready", 600)
            for i in range(args.events):
                for arm in (arms if i % 2 == 0 else arms[::-1]):
                    arm.one(i)
        finally:
            texts = {arm.label: arm.daemon.text() for arm in arms}
            for arm in arms:
                arm.daemon.stop()
    for arm in arms:
        text = texts[arm.label]
        lines.append(latency_line(arm.label, arm.latencies, 3,
                                  f"(load at each send: {' '.join(f'{x:.1f}' for x in arm.loads)})"))
        lines.append(f"         log: notify_sent {text.count('event=notify_sent')}, notify_failed "
                     f"{text.count('event=notify_failed')}, notify_dropped {text.count('event=notify_dropped')}, "
                     f"the webhook's secret path in the log: {'YES' if 's3cr3t' in text else 'no'}")
    healthy, hanging = arms[0].latencies, arms[1].latencies
    diffs = [b - a for a, b in zip(healthy, hanging)]
    lines += [f"hanging - healthy, paired by notice: median {statistics.median(diffs):+.3f} s "
              f"({' '.join(f'{x:+.2f}' for x in diffs)}); medians' ratio "
              f"{statistics.median(hanging) / statistics.median(healthy):.2f}",
              f"connections the silent webhook held: {len(silent.held)}",
              "", "## what the healthy webhook received (JSON target), in order"]
    import json

    for req, _ in server.log:
        body = json.loads(req.get_data())
        lines.append(f"- [{body.get('event')}] {body.get('text')}")
    silent.close()
    server.stop()
    write_summary(lines, args.out, "notify_latency.txt")
    return 0


if __name__ == "__main__":
    sys.exit(main())
