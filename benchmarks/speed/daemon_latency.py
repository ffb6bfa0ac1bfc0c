"""Measure the running service: consumed -> first plan -> final plan, a burst, a stopped broker.

Usage::

    nice -n 5 .venv/bin/python benchmarks/speed/daemon_latency.py [--scenario sequential|burst|broker-stop|all]
        [--maps N] [--burst N] [--out benchmarks/results]
    nice -n 5 .venv/bin/python benchmarks/speed/daemon_latency.py --trees BASE_TREE NEW_TREE [--maps N]
        (the sequential scenario on two source trees side by side; see ``side_by_side``)

The real ``mushrooms run`` process with the *default* configuration
(``config.toml`` defaults: nside 256, hybrid solver, 30 s MILP limit, two
workers), except what a benchmark has to set: the loopback broker, topics,
the Kafka sink and ``allow_mock`` (the shared notices are mock events).
The broker is librdkafka's mock cluster on loopback.

Notices are *live-time copies*: the shared notices (``notices/live`` and
``notices/json`` preliminaries) and notices carrying the shared simulated
BNS maps (``skymaps/simulated/bns_o3``, base64 in a copy of a shared
notice), each with a fresh ``superevent_id``, ``time_created`` = now and
the merger 60 s before, so the plan is for the sky of the moment.

Latencies are the daemon's own, on one clock: a plan document's
``metrics.latency_s`` (notice consumed -> plan stored) plus the
``queued_s`` of its ``publish ... ok`` log line (stored -> acknowledged by
the outbound broker, acks=all); the outside view (our producer's ack ->
the message read from the outbound topic) is printed beside it.

Scenarios
---------
sequential
    One notice at a time; the next after the previous one's final plan.
burst
    ``--burst`` distinct events produced within one second; every first
    plan, the p95 and the last; daemon RSS before / peak / after.
broker-stop
    The outbound broker (a mock cluster in a process of its own) is
    SIGSTOPped for 60 s while notices arrive: planning goes on, the plans
    go out once it returns, and every key is published with one content.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import signal
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import confluent_kafka
import psutil

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "daemon"))
from daemon_helpers import BIG, Broker, Daemon  # noqa: E402

from mushrooms.tool.live_notice import retime_skymap  # noqa: E402  (DATE-OBS / MJD-OBS moved to the merger)

SHARED = Path("/work/shared/data")
TEMPLATES = [SHARED / "notices/json/MS181101ab-preliminary.json"] + sorted(
    p for p in (SHARED / "notices/live").glob("*-preliminary.json"))
SIMULATED = sorted((SHARED / "skymaps/simulated/bns_o3").glob("*.fits"), key=lambda p: int(p.stem))

CONFIG = """
[policy]
allow_mock = true

[kafka]
topics = ["{topic}"]
group_id = "{group}"
assignment = "manual"

[outbound]
sink = "kafka"
topic = "{out}"
{out_bootstrap}
"""


def iso(t: datetime) -> str:
    return t.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def live_notices(n_maps: int) -> list[tuple[str, dict[str, Any]]]:
    """(source name, notice template) for the shared CBC notices, then notices with simulated maps.

    The shared Burst notice (S230528ay) is left out: the policy ignores it, so it has no plan to time.
    """
    out = [(p.name, json.loads(p.read_text())) for p in TEMPLATES]
    out = [(n, d) for n, d in out if (d.get("event") or {}).get("group") == "CBC"]
    base = json.loads(TEMPLATES[0].read_text())
    for p in SIMULATED[:n_maps]:
        doc = json.loads(json.dumps(base))
        doc["event"]["skymap"] = base64.b64encode(p.read_bytes()).decode()
        out.append((f"bns_o3/{p.name}", doc))
    return out


def new_sid(tag: str, i: int) -> str:
    """A fresh mock superevent id of today, e.g. ``MS261201qab`` (letters only after the date)."""
    a = "abcdefghijklmnopqrstuvwxyz"
    return f"MS{datetime.now(timezone.utc):%y%m%d}{tag}{a[i // 26 % 26]}{a[i % 26]}"


def stamp(doc: dict[str, Any], sid: str) -> bytes:
    """A live-time copy: new id, created now, merger 60 s ago (in the notice and in its sky maps)."""
    d = dict(doc)
    d["superevent_id"] = sid
    now = datetime.now(timezone.utc)
    merger = now - timedelta(seconds=60)
    d["time_created"] = iso(now)
    d["event"] = dict(d["event"], time=iso(merger))
    if d["event"].get("skymap"):
        d["event"]["skymap"] = retime_skymap(d["event"]["skymap"], merger)
    ext = d.get("external_coinc")
    if isinstance(ext, dict) and ext.get("combined_skymap"):
        d["external_coinc"] = dict(ext, combined_skymap=retime_skymap(ext["combined_skymap"], merger))
    return json.dumps(d).encode()


class Outbound:
    """Reads the outbound topic in a thread; remembers when each message arrived."""

    def __init__(self, bootstrap: str, topic: str) -> None:
        self.c = confluent_kafka.Consumer({
            "bootstrap.servers": bootstrap, "group.id": f"bench-{time.time_ns()}", "enable.auto.commit": False,
            "auto.offset.reset": "earliest", "fetch.max.bytes": BIG, "max.partition.fetch.bytes": BIG,
            "fetch.wait.max.ms": 10, "log_level": 3,
        })
        md = self.c.list_topics(topic, timeout=30)
        parts = sorted(md.topics[topic].partitions)
        self.c.assign([confluent_kafka.TopicPartition(topic, p, confluent_kafka.OFFSET_BEGINNING) for p in parts])
        self.messages: list[tuple[float, bytes | None, dict[str, Any]]] = []
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._t = threading.Thread(target=self._run, daemon=True)
        self._t.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            for m in self.c.consume(100, 0.05):
                if m.error() is None:
                    with self._lock:
                        self.messages.append((time.time(), m.key(), json.loads(m.value())))

    def snapshot(self) -> list[tuple[float, bytes | None, dict[str, Any]]]:
        with self._lock:
            return list(self.messages)

    def close(self) -> None:
        self._stop.set()
        self._t.join(5)
        self.c.close()


def sid_of(m: dict[str, Any]) -> str | None:
    return m.get("superevent_id") or (m.get("event") or {}).get("superevent_id")


def is_final(m: dict[str, Any]) -> bool:
    return m.get("type") == "plan_final" or (m.get("type") in ("plan", "not_observable") and m.get("final") is True)


def wait_until(cond, timeout_s: float, daemon: Daemon | None = None, every: float = 0.05) -> bool:
    end = time.monotonic() + timeout_s
    while not cond():
        if daemon is not None:
            daemon.alive()
        if time.monotonic() > end:
            return False
        time.sleep(every)
    return True


def queued_by_key(log_text: str) -> dict[str, float]:
    """publish key -> queued_s (stored -> acknowledged) from the daemon log (first ok publish)."""
    out: dict[str, float] = {}
    for m in re.finditer(r"publish key=(\S+) kind=\S+ superevent_id=\S+ ok queued_s=([0-9.]+)", log_text):
        out.setdefault(m.group(1), float(m.group(2)))
    return out


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    if not xs:
        return float("nan")
    k = min(len(xs) - 1, max(0, int(round(q / 100 * (len(xs) - 1)))))
    return xs[k]


def start_daemon(work: Path, broker: Broker, out_bootstrap: str | None = None,
                 n_topics: int = 1, tree: Path | None = None) -> tuple[Daemon, list[str], str, float]:
    """The daemon on ``n_topics`` input topics.

    librdkafka's mock broker keeps only about 5 MB per partition (older
    messages are deleted: a consumer then skips to the new log start), and
    an auto-created topic has 4 partitions; a burst of fifty 1 MB notices
    is therefore spread over several input topics so that all stay readable.
    """
    stamp_ns = time.time_ns()
    topics, out = [f"gwalert-{stamp_ns}-{k}" for k in range(n_topics)], f"plans-{stamp_ns}"
    for topic in topics:
        broker.ensure_topic(topic)
    if out_bootstrap is None:
        broker.ensure_topic(out)
    cfg = work / "config.toml"
    cfg.write_text(CONFIG.format(topic='", "'.join(topics), group=f"mushrooms-{time.time_ns()}", out=out,
                                 out_bootstrap=f'bootstrap = "{out_bootstrap}"' if out_bootstrap else ""))
    t0 = time.monotonic()
    env = None if tree is None else {"PYTHONPATH": str(tree)}  # that tree's mushrooms (--trees)
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(work / "state.sqlite")],
               env=env)
    d.wait_log("event=service_ready", 300)
    startup = time.monotonic() - t0
    return d, topics, out, startup


def latencies(msgs: list[tuple[float, bytes | None, dict[str, Any]]], queued: dict[str, float],
              sids: dict[str, float]) -> dict[str, dict[str, float]]:
    """Per superevent: first / final (inside: consumed -> acked) and outside (produce ack -> read)."""
    res: dict[str, dict[str, float]] = {}
    first_doc: dict[str, dict[str, Any]] = {}
    for t, _, m in msgs:
        sid = sid_of(m)
        if sid not in sids:
            continue
        r = res.setdefault(sid, {})
        # the first answer: a plan, or the not_observable document published in its place
        if m.get("type") in ("plan", "not_observable") and "first" not in r:
            r["first"] = m["metrics"]["latency_s"] + queued.get(m["plan_id"], float("nan"))
            r["first_out"] = t - sids[sid]
            r["first_cov"] = m["metrics"]["coverage"]
            first_doc[sid] = m
        if is_final(m) and "final" not in r:
            if m["type"] in ("plan", "not_observable"):
                r["final"] = m["metrics"]["latency_s"] + queued.get(m["plan_id"], float("nan"))
                r["revision"] = m["revision"]
                r["final_cov"] = m["metrics"]["coverage"]
            else:
                # plan_final: latency of the optimisation's verdict, measured outside only
                r["final"] = t - sids[sid] - (r["first_out"] - r["first"]) if "first" in r else float("nan")
                r["revision"] = 1
                r["final_cov"] = r.get("first_cov", float("nan"))
            r["final_out"] = t - sids[sid]
    return res


# ---------------------------------------------------------------- scenarios
def sequential(broker: Broker, work: Path, n_maps: int, report: list[str]) -> None:
    d, (topic,), out, startup = start_daemon(work, broker)
    reader = Outbound(broker.bootstrap, out)
    sids: dict[str, float] = {}
    names: dict[str, str] = {}
    try:
        for i, (name, doc) in enumerate(live_notices(n_maps)):
            sid = new_sid("q", i)
            names[sid] = name
            broker.produce(topic, stamp(doc, sid), key=sid.encode())
            sids[sid] = time.time()
            ok = wait_until(lambda: any(is_final(m) and sid_of(m) == sid for _, _, m in reader.snapshot()), 400, d)
            print(f"  {name}: {'final' if ok else 'NO FINAL within 400 s'}", flush=True)
    finally:
        time.sleep(1)
        msgs = reader.snapshot()
        reader.close()
        d.stop()
    lat = latencies(msgs, queued_by_key(d.text()), sids)
    report.append(f"## sequential: {len(sids)} notices one at a time, defaults (hybrid, nside 256)")
    report.append(f"daemon start-up (process launch -> event=service_ready): {startup:.2f} s; "
                  + _warm_line(d.text()))
    report.append("notice | first s (outside) | final s (outside) | revision | coverage first -> final")
    for sid, r in lat.items():
        report.append(f"{names[sid]} | {r.get('first', float('nan')):.3f} ({r.get('first_out', float('nan')):.3f})"
                      f" | {r.get('final', float('nan')):.3f} ({r.get('final_out', float('nan')):.3f})"
                      f" | {r.get('revision', '-')} | {r.get('first_cov', float('nan')):.4f} -> "
                      f"{r.get('final_cov', float('nan')):.4f}")
    firsts = [r["first"] for r in lat.values() if "first" in r]
    finals = [r["final"] for r in lat.values() if "final" in r]
    report.append(f"consumed -> first plan published: p50 {statistics.median(firsts):.3f} s, "
                  f"p95 {pct(firsts, 95):.3f} s, max {max(firsts):.3f} s (n={len(firsts)})")
    report.append(f"consumed -> final plan: p50 {statistics.median(finals):.3f} s, p95 {pct(finals, 95):.3f} s, "
                  f"max {max(finals):.3f} s (n={len(finals)}); revision 2 published for "
                  f"{sum(1 for r in lat.values() if r.get('revision') == 2)} of {len(lat)}")
    report.append("")


def side_by_side(broker: Broker, work: Path, n_maps: int, trees: list[Path], report: list[str]) -> None:
    """The sequential scenario on two source trees at once: one daemon each, notice by notice alternately.

    Each notice goes to one daemon, then (after its final plan) a fresh copy to the
    other; the tree that goes first alternates per notice, so a slow spell of a
    shared machine falls on both.  Only one daemon plans at a time.
    """
    names = [t.name for t in trees]
    daemons, readers, topics = [], [], []
    for k, tree in enumerate(trees):
        (work / names[k]).mkdir()
        d, (topic,), out, _ = start_daemon(work / names[k], broker, tree=tree)
        daemons.append(d), topics.append(topic), readers.append(Outbound(broker.bootstrap, out))
    sids: list[dict[str, float]] = [{}, {}]
    labels: dict[str, str] = {}
    try:
        for i, (name, doc) in enumerate(live_notices(n_maps)):
            for k in ((0, 1) if i % 2 == 0 else (1, 0)):
                sid = new_sid("ab"[k], i)
                labels[sid] = name
                broker.produce(topics[k], stamp(doc, sid), key=sid.encode())
                sids[k][sid] = time.time()
                ok = wait_until(lambda: any(is_final(m) and sid_of(m) == sid for _, _, m in readers[k].snapshot()),
                                400, daemons[k])
                print(f"  {names[k]} {name}: {'final' if ok else 'NO FINAL within 400 s'} "
                      f"(load {os.getloadavg()[0]:.1f})", flush=True)
    finally:
        time.sleep(1)
        msgs = [r.snapshot() for r in readers]
        for r, d in zip(readers, daemons):
            r.close()
            d.stop()
    lat = [latencies(msgs[k], queued_by_key(daemons[k].text()), sids[k]) for k in range(2)]
    report.append(f"## side by side: {len(sids[0])} notices one at a time to each of {names[0]} and {names[1]}, "
                  f"defaults, alternating")
    report.append(f"notice | {names[0]} first s | final s | rev | cov first -> final | {names[1]} first s | "
                  f"final s | rev | cov first -> final")
    by_label = [{labels[s]: r for s, r in lat[k].items()} for k in range(2)]
    for label in dict.fromkeys(labels.values()):
        cells = []
        for k in range(2):
            r = by_label[k].get(label, {})
            cells.append(f"{r.get('first', float('nan')):.3f} | {r.get('final', float('nan')):.3f} | "
                         f"{r.get('revision', '-')} | {r.get('first_cov', float('nan')):.4f} -> "
                         f"{r.get('final_cov', float('nan')):.4f}")
        report.append(f"{label} | {cells[0]} | {cells[1]}")
    for k in range(2):
        firsts = [r["first"] for r in lat[k].values() if "first" in r]
        finals = [r["final"] for r in lat[k].values() if "final" in r]
        report.append(f"{names[k]}: first p50 {statistics.median(firsts):.3f} s, p95 {pct(firsts, 95):.3f} s, "
                      f"max {max(firsts):.3f} s; optimised/final p50 {statistics.median(finals):.3f} s, "
                      f"p95 {pct(finals, 95):.3f} s, max {max(finals):.3f} s (n={len(finals)}); revision 2 for "
                      f"{sum(1 for r in lat[k].values() if r.get('revision') == 2)}; mean final coverage "
                      f"{statistics.mean(r.get('final_cov', 0.0) for r in lat[k].values()):.4f}")
    report.append("")


def _warm_line(text: str) -> str:
    m = re.search(r"event=warm_up cache_s=([0-9.]+) total_s=([0-9.]+)", text)
    s = re.search(r"event=service_ready .*startup_s=([0-9.]+)", text)
    return (f"of which warm-up {m.group(2)} s (visibility of two nights {m.group(1)} s)" if m else "") + \
        (f", service init -> ready {s.group(1)} s" if s else "")


def burst(broker: Broker, work: Path, n: int, report: list[str], final_wait_s: float) -> None:
    d, topics, out, startup = start_daemon(work, broker, n_topics=max(1, n // 12 + 1))
    proc = psutil.Process(d.proc.pid)
    rss: list[float] = []
    sampling = threading.Event()

    def sample() -> None:
        while not sampling.is_set():
            try:
                rss.append(proc.memory_info().rss / 2**20)
            except psutil.Error:
                return
            time.sleep(0.2)

    reader = Outbound(broker.bootstrap, out)
    time.sleep(2)
    before = proc.memory_info().rss / 2**20
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    notices = live_notices(len(SIMULATED))
    sids: dict[str, float] = {}
    payloads = []
    for i in range(n):
        name, doc = notices[i % len(notices)]
        sid = new_sid("b", i)
        payloads.append((sid, stamp(doc, sid)))
    t0 = time.time()
    acked: dict[str, float] = {}
    for k, (sid, raw) in enumerate(payloads):
        broker.producer.produce(topics[k % len(topics)], value=raw, key=sid.encode(),
                                on_delivery=lambda err, msg, sid=sid: acked.__setitem__(sid, time.time()))
        broker.producer.poll(0)
    broker.producer.flush(30)
    produce_s = time.time() - t0
    sids = dict(acked)
    all_first = wait_until(lambda: len({sid_of(m) for _, _, m in reader.snapshot()
                                        if m.get("type") in ("plan", "not_observable")}
                                        & set(sids)) == n, 600, d, every=0.2)
    t_first = time.time() - t0
    all_final = wait_until(lambda: len({sid_of(m) for _, _, m in reader.snapshot() if is_final(m)} & set(sids)) == n,
                           final_wait_s, d, every=0.5)
    t_final = time.time() - t0
    time.sleep(2)
    after = proc.memory_info().rss / 2**20
    sampling.set()
    msgs = reader.snapshot()
    reader.close()
    text = d.text()
    d.stop()
    lat = latencies(msgs, queued_by_key(text), sids)
    firsts = [r["first"] for r in lat.values() if "first" in r]
    finals = [r["final"] for r in lat.values() if "final" in r]
    report.append(f"## burst: {n} distinct events produced in {produce_s:.2f} s, defaults")
    report.append(f"daemon start-up: {startup:.2f} s; " + _warm_line(text))
    report.append(f"every event got a first plan: {all_first} ({len(firsts)}/{n}), all within {t_first:.1f} s "
                  f"of the first produce")
    if firsts:
        report.append(f"consumed -> first plan published: p50 {statistics.median(firsts):.3f} s, "
                      f"p95 {pct(firsts, 95):.3f} s, last {max(firsts):.3f} s")
    report.append(f"final plans: {len(finals)}/{n} within {t_final:.0f} s (all: {all_final}); p50 "
                  f"{statistics.median(finals) if finals else float('nan'):.1f} s, last "
                  f"{max(finals) if finals else float('nan'):.1f} s; revision 2 for "
                  f"{sum(1 for r in lat.values() if r.get('revision') == 2)}")
    report.append(f"daemon RSS: before {before:.0f} MiB, peak {max(rss + [before]):.0f} MiB, after {after:.0f} MiB")
    report.append("")


BROKER_PROC = r"""
import time
from mushrooms.tool.loopback_broker import LoopbackBroker
b = LoopbackBroker()
print(b.bootstrap, flush=True)
while True:
    time.sleep(1)
"""


def broker_stop(broker: Broker, work: Path, report: list[str], stop_s: float = 60.0, n: int = 4) -> None:
    bp = subprocess.Popen([sys.executable, "-c", BROKER_PROC], stdout=subprocess.PIPE, text=True)
    try:
        out_bootstrap = bp.stdout.readline().strip()
        d, (topic,), out, startup = start_daemon(work, broker, out_bootstrap)
        admin = confluent_kafka.Producer({"bootstrap.servers": out_bootstrap, "log_level": 3})
        for _ in range(50):
            t = admin.list_topics(out, timeout=10).topics.get(out)
            if t is not None and t.error is None and t.partitions:
                break
            time.sleep(0.1)
        reader = Outbound(out_bootstrap, out)
        notices = live_notices(n)
        sids: dict[str, float] = {}
        os.kill(bp.pid, signal.SIGSTOP)
        t_stop = time.time()
        for i in range(n):
            name, doc = notices[i]
            sid = new_sid("s", i)
            broker.produce(topic, stamp(doc, sid), key=sid.encode())
            sids[sid] = time.time()
        planned = wait_until(lambda: d.text().count("event=job_first_plan") >= n, stop_s, d)
        t_planned = time.time() - t_stop
        text_during = d.text()
        time.sleep(max(0.0, stop_s - (time.time() - t_stop)))
        os.kill(bp.pid, signal.SIGCONT)
        t_cont = time.time()
        got = wait_until(lambda: len({sid_of(m) for _, _, m in reader.snapshot() if is_final(m)} & set(sids)) == n,
                         400, d, every=0.5)
        t_all = time.time() - t_cont
        time.sleep(3)
        msgs = reader.snapshot()
        reader.close()
        text = d.text()
        state = work / "state.sqlite"
        d.stop()
    finally:
        try:
            os.kill(bp.pid, signal.SIGCONT)
        except ProcessLookupError:
            pass
        bp.kill()
        bp.wait(10)
    with sqlite3.connect(state) as c:
        rows = c.execute("SELECT key, body, published_at FROM outbox").fetchall()
    by_key: dict[str, set[str]] = {}
    for _, _, m in msgs:
        key = m.get("plan_id") if m.get("type") in ("plan", "not_observable") else (
            f"{m.get('plan_id')}-final" if m.get("type") == "plan_final" else m.get("withdrawal_id"))
        by_key.setdefault(key, set()).add(json.dumps(m, sort_keys=True))
    stored = {k: json.dumps(json.loads(b), sort_keys=True) for k, b, _ in rows}
    lost = sorted(set(stored) - set(by_key))
    differing = sorted(k for k, v in by_key.items() if len(v) > 1 or (k in stored and v != {stored[k]}))
    copies = sum(1 for _, _, m in msgs) - len(by_key)
    fails = text.count("event=publish_failed")
    first_lat = [float(x) for x in re.findall(r"event=job_first_plan .*?latency_s=([0-9.]+)", text_during)]
    report.append(f"## broker-stop: outbound broker SIGSTOPped {stop_s:.0f} s while {n} notices arrived")
    report.append(f"planning went on: {n} first plans made while stopped: {planned}, the last {t_planned:.1f} s "
                  f"after the stop (stored, consumed -> stored: {', '.join(f'{x:.2f}' for x in first_lat)} s)")
    report.append(f"publish failures logged while stopped: {fails} (back-off retries)")
    report.append(f"after SIGCONT every event's final message out: {got}, {t_all:.1f} s after SIGCONT")
    report.append(f"outbox rows {len(rows)}, all marked published: {all(r[2] for r in rows)}; keys on the topic "
                  f"{len(by_key)}; lost: {lost or 'none'}; extra copies (same key): {copies}; "
                  f"keys with differing content: {differing or 'none'}")
    report.append("")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenario", default="all", choices=["sequential", "burst", "broker-stop", "all"])
    ap.add_argument("--maps", type=int, default=8, help="simulated maps in the sequential run (after the 5 shared)")
    ap.add_argument("--burst", type=int, default=50)
    ap.add_argument("--burst-final-wait", type=float, default=420.0)
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "speed"))
    ap.add_argument("--trees", nargs=2, type=Path, metavar=("BASE", "NEW"),
                    help="the sequential scenario side by side on two source trees (one daemon each, notices "
                         "alternating); writes daemon_latency_side_by_side.txt")
    a = ap.parse_args()
    broker = Broker()
    report = [f"# daemon_latency.py {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC",
              f"machine: {os.cpu_count()} cores, load average at start {os.getloadavg()[0]:.1f} "
              f"(other work on the machine inflates every latency below; see the load after each scenario)", ""]
    scen = ["sequential", "burst", "broker-stop"] if a.scenario == "all" else [a.scenario]
    if a.trees:
        scen, a.scenario = ["side_by_side"], "side_by_side"
    for s in scen:
        work = Path(tempfile.mkdtemp(prefix=f"mushrooms-{s}-"))
        print(f"[{s}] in {work}", flush=True)
        if s == "side_by_side":
            side_by_side(broker, work, a.maps, [t.resolve() for t in a.trees], report)
        elif s == "sequential":
            sequential(broker, work, a.maps, report)
        elif s == "burst":
            burst(broker, work, a.burst, report, a.burst_final_wait)
        else:
            broker_stop(broker, work, report)
        report.append(f"(load average after {s}: {os.getloadavg()[0]:.1f})")
        report.append("")
        print("\n".join(report), flush=True)
    out = Path(a.out) / f"daemon_latency_{a.scenario}.txt"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(report) + "\n")
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
