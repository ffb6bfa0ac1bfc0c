"""8 random SIGKILLs during a stream of 6 live events.

The real daemon (``mushrooms run`` subprocess, tests/daemon/daemon_helpers.Daemon)
on librdkafka's mock cluster (loopback), a 4-partition input topic, real SQLite,
the hybrid solver at nside 64 (first plan greedy, then the optimised revision:
the crash accounting is about the optimisation stage), default
``[daemon] max_jobs``.  Six PRELIMINARY notices (real sample maps) are produced
while the daemon is SIGKILLed 8 times at random moments (seeded) after it is
ready; then one last start runs until every event has its final message.

Reported: decision rows per notice (must be exactly 1), messages never stored,
plan ids published with two contents (must be none), and per event the messages
published, whether the event ends with its final message (a plan revision with
``final: true`` or a ``plan_final``; before the fallback 5 of 6 events lost it), the jobs'
attempts and status.

    PYTHONPATH=$PWD nice -n 5 python benchmarks/attacks/sigkill_attack.py [--seed 25] [--kills 8]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import random
import sqlite3
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests" / "daemon")]

from daemon_helpers import Broker, Daemon, notice_path, write_config  # noqa: E402

MAPS = ["MS181101ab-preliminary.json", "MS260605l-preliminary.json", "MS230425l-preliminary.json",
        "MS230425k-preliminary.json", "S230528ay-preliminary.json", "MS181101ab-preliminary.json"]
EXTRA = """
"""


def rows(state: Path, sql: str, *args) -> list[tuple]:
    with sqlite3.connect(f"file:{state}?mode=ro", uri=True) as c:
        return c.execute(sql, args).fetchall()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=25)
    ap.add_argument("--kills", type=int, default=8)
    ap.add_argument("--mode", choices=("random", "during-jobs"), default="random",
                    help="random: kill 1-12 s after ready (one new event per start); during-jobs: three events "
                         "at each of the first two starts, each kill 0.5-8 s after a job started in that run")
    ap.add_argument("--out", default=None)
    ap.add_argument("--tree", default=str(ROOT), help="tree whose mushrooms package the daemon runs")
    ap.add_argument("--label", default="")
    ap.add_argument("--time-limit", type=float, default=8.0, help="[scheduler] time_limit_s (longer: kills land mid-job)")
    ap.add_argument("--events", type=int, default=6, help="live events (2: every kill hits both running jobs)")
    a = ap.parse_args()
    rnd = random.Random(a.seed)
    a.out = a.out or str(ROOT / "benchmarks" / "results" / "attacks" / "sigkill_attack" / f"sigkill_attack_{a.mode}{a.label}.txt")
    work = Path(tempfile.mkdtemp(prefix="mushrooms-kill-"))
    load0 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    broker = Broker()
    topic, out_topic, group = broker.fresh_topics()
    cfg = write_config(work / "config.toml", topic, out_topic, group)
    text = cfg.read_text().replace('solver = "greedy"', f'solver = "hybrid"\ntime_limit_s = {a.time_limit}')
    cfg.write_text(text)
    state = work / "state.sqlite"
    args = ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)]
    env = {"PYTHONPATH": a.tree}
    started: list[Daemon] = []
    kills: list[str] = []
    produced: list[tuple[int, int]] = []
    day = time.strftime("%y%m%d", time.gmtime())
    sids = [f"MS{day}k{chr(97 + i)}" for i in range(a.events)]
    created = datetime.now(timezone.utc).replace(microsecond=0) - timedelta(minutes=10)

    def produce(i: int) -> None:
        doc = json.loads(notice_path("MS181101ab-preliminary.json").read_bytes())
        doc["superevent_id"] = sids[i]
        doc["time_created"] = (created + timedelta(seconds=i)).strftime("%Y-%m-%dT%H:%M:%SZ")
        doc["event"]["skymap"] = json.loads(notice_path(MAPS[i]).read_bytes())["event"]["skymap"]
        produced.append(broker.produce(topic, json.dumps(doc).encode(), key=sids[i].encode()))

    t0 = time.monotonic()
    nxt = 0
    for k in range(a.kills):
        d = Daemon(work, args, env=env)
        started.append(d)
        d.wait_log("event=service_ready", 300)
        # a new event at most every kill until all six are out (the stream), then kills only
        if a.mode == "random":
            if nxt < len(sids):
                produce(nxt)
                nxt += 1
            delay = rnd.uniform(1.0, 12.0)
            time.sleep(delay)
        else:
            for _ in range(3):
                if nxt < len(sids):
                    produce(nxt)
                    nxt += 1
            try:
                d.wait_log("event=job_started", 60)
            except AssertionError:
                pass
            delay = rnd.uniform(0.5, 8.0)
            time.sleep(delay)
        text = d.text()
        kills.append(f"kill {k + 1}: {delay:.1f} s after {'service_ready+produce' if a.mode == 'random' else 'a job_started'}; in this run: "
                     f"{text.count('event=job_started')} job starts, {text.count('publish key=')} publishes")
        d.kill9()
    d = Daemon(work, args, env=env)
    started.append(d)
    d.wait_log("event=service_ready", 300)
    while nxt < len(sids):
        produce(nxt)
        nxt += 1

    reader = broker.reader(out_topic, f"reader-{group}")

    def final_of(ms: list[dict], sid: str) -> bool:
        mine = [m for m in ms if ((m.get("event") or {}).get("superevent_id") or m.get("superevent_id")) == sid]
        return any(m.get("type") == "plan_final" or (m.get("type") in ("plan", "not_observable") and m.get("final"))
                   for m in mine)

    try:
        reader.wait_for(lambda ms: all(final_of(ms, s) for s in sids), 900, alive=d.alive)
        all_final_seen = True
    except AssertionError:
        all_final_seen = False
    msgs = reader.drain(5.0)  # the outbox drains asynchronously
    reader.close()
    rc = d.stop()
    wall = time.monotonic() - t0
    load1 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    logs = "\n".join(x.text() for x in started)

    per_notice = rows(state, "SELECT n.notice_id, n.origin, COUNT(d.decision_id) FROM notices n LEFT JOIN decisions d"
                             " USING(notice_id) GROUP BY n.notice_id")
    stored = set()
    for _, o, _ in per_notice:
        if o.startswith("kafka:"):
            _, _t, part, off = o.rsplit(":", 3)
            stored.add((int(part), int(off)))
    never = sorted(set(produced) - stored)
    contents: dict[tuple, set[str]] = {}
    for m in msgs:
        key = (m.get("type"), m.get("plan_id") or m.get("withdrawal_id"), m.get("revision"))
        contents.setdefault(key, set()).add(hashlib.sha256(json.dumps(m, sort_keys=True).encode()).hexdigest())
    two = {k: len(v) for k, v in contents.items() if len(v) > 1}
    lines = [f"# benchmarks/attacks/sigkill_attack.py {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, seed {a.seed}, mode {a.mode}",
             f"# command: PYTHONPATH=$PWD nice -n 5 python benchmarks/attacks/sigkill_attack.py --seed {a.seed} "
             f"--kills {a.kills} --mode {a.mode} --tree {a.tree} --events {a.events} --time-limit {a.time_limit}",
             f"# uptime before: {load0}", f"# uptime after:  {load1}",
             f"# solver hybrid (time_limit_s {a.time_limit:g}), nside 64, max_jobs default, 4-partition input topic, wall {wall:.0f} s,"
             f" final daemon exit {rc}", ""]
    lines += kills
    lines += ["",
              f"notices stored: {len(per_notice)}; decision rows per notice: "
              f"{sorted({c for _, _, c in per_notice})} (exactly one each: {all(c == 1 for _, _, c in per_notice)})",
              f"messages produced: {len(produced)}; never stored: {never}",
              f"published messages: {len(msgs)}; (type, id, revision) published with two contents: {two or 'none'}",
              f"redelivered identical copies: {len(msgs) - len(contents)}",
              f"every event's final message seen within 900 s of the last start: {all_final_seen}", ""]
    ok_events = 0
    for sid in sids:
        mine = [m for m in msgs if ((m.get("event") or {}).get("superevent_id") or m.get("superevent_id")) == sid]
        seq = [f"{m.get('type')}(rev {m.get('revision')}, final {m.get('final')})" for m in mine]
        jobs = rows(state, "SELECT job_id, status, attempts, reason FROM jobs WHERE superevent_id=?", sid)
        fin = final_of(msgs, sid)
        ok_events += fin
        lines.append(f"{sid}: ends with its final message: {fin}; published: {', '.join(seq) or '-'}")
        for j in jobs:
            lines.append(f"    job {j[0]}: status={j[1]} attempts={j[2]} reason={j[3]!r}")
    lines += ["", f"summary: {ok_events}/{len(sids)} events end with plan_final or a final revision; "
              f"fallbacks after repeated crashes in the logs: {logs.count('fallback=greedy')}; "
              f"Tracebacks in the logs: {logs.count('Traceback')}"]
    out = "\n".join(lines) + "\n"
    print(out)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(out)
    Path(a.out).with_suffix(".daemon.log").write_text(logs)
    ok = ok_events == len(sids) and not two and not never and all(c == 1 for _, _, c in per_notice)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
