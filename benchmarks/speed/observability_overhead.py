"""First-plan latency with the metrics listener on vs off, paired in one run.

Usage::

    nice -n 5 .venv/bin/python benchmarks/speed/observability_overhead.py [--pairs N] [--scrape-s S]
        [--out benchmarks/results]

Two real ``mushrooms run`` processes on one loopback mock broker, each on
its own input and output topics: *off* (no ``metrics_address``) and *on*
(``metrics_address`` set, and ``/metrics`` plus ``/readyz`` scraped every
``--scrape-s`` seconds, default 1 s, fifteen times Prometheus' usual rate,
for the whole run).  Both use the default configuration except
``solver = "greedy"`` (the first plan is the greedy revision 1 either way;
this keeps each notice to a few seconds).  Each pair sends the same
live-time notice (same sky map, new superevent ids) to one daemon, waits
for its plan, then to the other; the order alternates pair by pair.

Latency: the plan document's ``metrics.latency_s`` (notice consumed ->
plan stored, the daemon's own clock) and the outside view (our producer's
acknowledgement -> the plan read from the output topic).  The machine is
shared with other work: the numbers are indicative; the load average is
printed beside them.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "daemon"))
sys.path.insert(0, str(REPO / "benchmarks" / "speed"))
from daemon_helpers import Broker, Daemon  # noqa: E402
from daemon_latency import Outbound, live_notices, new_sid, sid_of, stamp, wait_until  # noqa: E402

CONFIG = """
[scheduler]
solver = "greedy"

[policy]
allow_mock = true

[daemon]
{metrics}

[kafka]
topics = ["{topic}"]
group_id = "{group}"
assignment = "manual"

[outbound]
sink = "kafka"
topic = "{out}"
"""


def start(broker: Broker, work: Path, name: str, port: int | None) -> tuple[Daemon, str, str]:
    work.mkdir(parents=True, exist_ok=True)
    topic, out = f"gwalert-{name}-{time.time_ns()}", f"plans-{name}-{time.time_ns()}"
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    cfg = work / "config.toml"
    cfg.write_text(CONFIG.format(topic=topic, out=out, group=f"mushrooms-{time.time_ns()}",
                                 metrics=f'metrics_address = "127.0.0.1:{port}"' if port else ""))
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(work / "state.sqlite")])
    d.wait_log("event=service_ready", 300)
    return d, topic, out


def scraper(port: int, every_s: float, stop: threading.Event, counts: dict[str, int], failed: list[str]) -> None:
    while not stop.wait(every_s):
        for path in ("/metrics", "/readyz"):
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=5) as r:
                    r.read()
                counts["ok"] += 1
            except urllib.error.HTTPError as exc:  # 503 from /readyz: say which check failed
                counts["other"] += 1
                failed.append(f"{path} {exc.code}: {exc.read().decode()[:300]}")
            except OSError as exc:
                counts["other"] += 1
                failed.append(f"{path}: {exc}")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=12)
    ap.add_argument("--scrape-s", type=float, default=1.0)
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "speed"))
    a = ap.parse_args()
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    broker = Broker()
    base = Path(tempfile.mkdtemp(prefix="mushrooms-overhead-"))
    load0 = os.getloadavg()
    off, topic_off, out_off = start(broker, base / "off", "off", None)
    on, topic_on, out_on = start(broker, base / "on", "on", port)
    readers = {"off": Outbound(broker.bootstrap, out_off), "on": Outbound(broker.bootstrap, out_on)}
    daemons = {"off": (off, topic_off), "on": (on, topic_on)}
    stop = threading.Event()
    counts = {"ok": 0, "other": 0}
    failed: list[str] = []
    t = threading.Thread(target=scraper, args=(port, a.scrape_s, stop, counts, failed), daemon=True)
    t.start()
    notices = live_notices(max(0, a.pairs - 5))
    rows: list[tuple[str, dict[str, tuple[float, float]]]] = []
    try:
        for i in range(a.pairs):
            name, doc = notices[i % len(notices)]
            order = ("off", "on") if i % 2 == 0 else ("on", "off")
            row: dict[str, tuple[float, float]] = {}
            for which in order:
                d, topic = daemons[which]
                sid = new_sid("o" if which == "off" else "n", i)
                broker.produce(topic, stamp(doc, sid), key=sid.encode())
                acked = time.time()
                reader = readers[which]
                ok = wait_until(lambda: any(sid_of(m) == sid and m.get("type") in ("plan", "not_observable")
                                            for _, _, m in reader.snapshot()), 300, d)
                if not ok:
                    raise SystemExit(f"no plan for {sid} ({which})")
                ts, _, m = next(x for x in reader.snapshot() if sid_of(x[2]) == sid)
                row[which] = (m["metrics"]["latency_s"], ts - acked)
            rows.append((name, row))
            print(f"  {name}: off {row['off'][0]:.3f} s, on {row['on'][0]:.3f} s", flush=True)
    finally:
        stop.set()
        t.join(5)
        for r in readers.values():
            r.close()
        off.stop()
        on.stop()
    load1 = os.getloadavg()
    diffs = [r["on"][0] - r["off"][0] for _, r in rows]
    diffs_out = [r["on"][1] - r["off"][1] for _, r in rows]
    inside_off, inside_on = [r["off"][0] for _, r in rows], [r["on"][0] for _, r in rows]
    lines = [f"# observability_overhead.py {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC",
             f"machine: {os.cpu_count()} cores shared with other work; load average {load0[0]:.1f} at start, "
             f"{load1[0]:.1f} at the end: indicative numbers",
             f"{a.pairs} pairs, defaults with solver greedy (nside 256); 'on' scraped /metrics + /readyz every "
             f"{a.scrape_s:g} s ({counts['ok']} answers, {counts['other']} errors or 503s)",
             "notice | off: consumed->stored s (outside s) | on: consumed->stored s (outside s)"]
    lines += [f"{n} | {r['off'][0]:.3f} ({r['off'][1]:.3f}) | {r['on'][0]:.3f} ({r['on'][1]:.3f})" for n, r in rows]
    lines += [f"first plan, consumed -> stored: median off {statistics.median(inside_off):.3f} s, on "
              f"{statistics.median(inside_on):.3f} s; paired difference on - off: median "
              f"{statistics.median(diffs):+.3f} s, mean {statistics.mean(diffs):+.3f} s "
              f"(min {min(diffs):+.3f}, max {max(diffs):+.3f})",
              f"outside view (producer ack -> plan read), paired difference on - off: median "
              f"{statistics.median(diffs_out):+.3f} s, mean {statistics.mean(diffs_out):+.3f} s"]
    lines += [f"scrape not 200: {x}" for x in failed]
    print("\n".join(lines))
    out = Path(a.out) / "observability_overhead.txt"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
