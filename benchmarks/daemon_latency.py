"""Measure notice consumed -> plan published with the real service (not a test).

Usage::

    .venv/bin/python tests/daemon/measure_latency.py [--solver greedy|hybrid|milp] [--runs 5]

Starts the librdkafka mock broker, one ``mushrooms run`` process (Kafka sink),
and produces the sample notices one at a time (MS181101ab, MS230425l,
MS260605l preliminaries; each run rewrites only the ``superevent_id`` so
that every notice is a new event).  For each notice it reports the
daemon's own measure (``latency_s`` in the ``event=job_done`` line: from the
moment ``consume()`` returned the notice to the broker's acknowledgement of
the plan, acks=all) and an outside one (producer ack -> plan read from the
outbound topic).  The first notice of the process is reported apart (cold
caches: footprints, imports).
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "daemon"))
from daemon_helpers import Broker, Daemon, notice_bytes, write_config  # noqa: E402

SAMPLES = [("MS181101ab-preliminary.json", "MS181101"), ("MS230425l-preliminary.json", "MS230425"),
           ("MS260605l-preliminary.json", "MS260605")]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--solver", default="greedy")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--time-limit", type=float, default=30.0)
    a = ap.parse_args()
    broker = Broker()
    work = Path(tempfile.mkdtemp(prefix="mushrooms-latency-"))
    topic, out = f"in-{time.time_ns()}", f"out-{time.time_ns()}"
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    cfg = write_config(work / "config.toml", topic, out, "latency")
    text = cfg.read_text().replace('solver = "greedy"\nnside = 64', f'solver = "{a.solver}"\ntime_limit_s = {a.time_limit}')
    cfg.write_text(text)
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(work / "s.sqlite")])
    reader = broker.reader(out, "latency-reader")
    d.wait_log("event=service_ready", 60)
    rows = []
    try:
        n = 0
        for run in range(-1, a.runs):  # run -1: warm-up (cold process)
            for name, prefix in SAMPLES:
                sid = f"{prefix}{'abcdefgh'[run + 1]}{'xyz'[SAMPLES.index((name, prefix))]}"
                raw = notice_bytes(name, superevent_id=sid)
                t0 = time.time()
                broker.produce(topic, raw, key=sid.encode())
                reader.wait_for(lambda ms: any((m.get("event") or {}).get("superevent_id") == sid for m in ms),
                                600, alive=d.alive)
                outside = time.time() - t0
                n += 1
                log = d.wait_log(f"event=job_done superevent_id={sid} ", 60)
                line = [ln for ln in log.splitlines() if f"event=job_done superevent_id={sid} " in ln][0]
                inside = float(re.search(r"latency_s=([0-9.]+)", line).group(1))
                rows.append((run, sid, inside, outside))
                print(f"run {run:2d} {sid:12s} consumed->published {inside:7.3f} s  (produce->read {outside:7.3f} s)",
                      flush=True)
    finally:
        reader.close()
        d.stop()
    warm = [r for r in rows if r[0] >= 0]
    ins = [r[2] for r in warm]
    print(f"\nsolver={a.solver} runs={a.runs} notices/run={len(SAMPLES)} (n={len(ins)}, warm process)")
    print(f"consumed->published: median {statistics.median(ins):.3f} s, max {max(ins):.3f} s")
    per_run_max = [max(r[2] for r in warm if r[0] == k) for k in range(a.runs)]
    print(f"per-run max: {', '.join(f'{x:.3f}' for x in per_run_max)}")
    cold = [r[2] for r in rows if r[0] < 0]
    print(f"cold first notices: {', '.join(f'{x:.3f}' for x in cold)} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
