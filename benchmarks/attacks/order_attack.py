"""Out-of-order notices through Kafka with 4 partitions.

A real ``mushrooms run`` subprocess (tests/daemon/daemon_helpers.Daemon) consumes
one 4-partition input topic of librdkafka's mock cluster on loopback and
publishes to an outbound topic; real SQLite state, greedy at nside 64 (the
service tests' config).  For distinct superevent ids it produces the issue's
sequences, in *arrival* order, each message on a partition of its own (keys
differ), waiting until the daemon has decided it (and finished its job)
before producing the next, so the arrival order is exactly the one written:

a. RETRACTION, then a PRELIMINARY created 300 s earlier arriving late
b. UPDATE (map A), then an older PRELIMINARY with another map (B)
c. PRELIMINARY -> RETRACTION -> an INITIAL created before the retraction
d. PRELIMINARY (map A), then an EARLYWARNING (map B) created 200 s before it
e. one event's EARLYWARNING (B, t-200), PRELIMINARY (B, t) and UPDATE (A, t+120)
   produced at once, newest first, with three keys (three partitions): the
   daemon's arrival order is the broker's/consumer's, not creation order
f. like e with a RETRACTION (t+3600) produced first and the three after it

Per sequence: the decisions stored (decisions table), the messages published on
the outbound topic, and whether the outcome is what creation order demands.

Run from the repository root, niced::

    PYTHONPATH=$PWD nice -n 5 python benchmarks/attacks/order_attack.py [--out benchmarks/results/attacks/order_attack/order_attack.txt]
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import json
import os
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

MAP_A = "MS181101ab-preliminary.json"  # the MS181101ab sample map
MAP_B = "MS260605l-preliminary.json"   # another event's map


def skymap_b64(name: str) -> str:
    return json.loads(notice_path(name).read_bytes())["event"]["skymap"]


def sha_of(name: str) -> str:
    return hashlib.sha256(base64.b64decode(skymap_b64(name))).hexdigest()


def iso(t: datetime) -> str:
    return t.strftime("%Y-%m-%dT%H:%M:%SZ")


def notice(kind: str, sid: str, created: datetime, map_of: str | None = MAP_A) -> bytes:
    """A sample MS181101ab notice of ``kind`` relabelled: id, time_created and (if any) its map."""
    name = {"EARLYWARNING": "MS181101ab-earlywarning.json", "PRELIMINARY": "MS181101ab-preliminary.json",
            "INITIAL": "MS181101ab-initial.json", "UPDATE": "MS181101ab-update.json",
            "RETRACTION": "MS181101ab-retraction.json"}[kind]
    doc = json.loads(notice_path(name).read_bytes())
    doc["superevent_id"] = sid
    doc["time_created"] = iso(created)
    if kind != "RETRACTION" and map_of is not None:
        doc["event"]["skymap"] = skymap_b64(map_of)
    return json.dumps(doc).encode()


def rows(state: Path, sql: str, *args) -> list[tuple]:
    with sqlite3.connect(f"file:{state}?mode=ro", uri=True) as c:
        return c.execute(sql, args).fetchall()


def find_sha(obj) -> list[str]:
    out = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k == "skymap_sha256" and isinstance(v, str):
                out.append(v)
            else:
                out += find_sha(v)
    elif isinstance(obj, list):
        for v in obj:
            out += find_sha(v)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None)
    ap.add_argument("--tree", default=str(ROOT), help="tree whose mushrooms package the daemon runs")
    ap.add_argument("--label", default="")
    a = ap.parse_args()
    a.out = a.out or str(ROOT / "benchmarks" / "results" / "attacks" / "order_attack" / f"order_attack{a.label}.txt")
    work = Path(tempfile.mkdtemp(prefix="mushrooms-order-"))
    load0 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    broker = Broker()
    topic, out_topic, group = broker.fresh_topics()
    nparts = len(broker.producer.list_topics(topic, timeout=10).topics[topic].partitions)
    cfg = write_config(work / "config.toml", topic, out_topic, group)
    state = work / "state.sqlite"
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)],
               env={"PYTHONPATH": a.tree})
    d.wait_log("event=service_ready", 240)
    reader = broker.reader(out_topic, f"reader-{group}")
    produced = [0]
    part = [0]

    def send(raw: bytes, wait: bool = True) -> int:
        p = part[0] % nparts
        part[0] += 1
        broker.producer.produce(topic, value=raw, key=f"k{produced[0]}".encode(), partition=p)
        assert broker.producer.flush(30) == 0
        produced[0] += 1
        if wait:
            settle()
        return p

    def settle(timeout_s: float = 600) -> None:
        end = time.monotonic() + timeout_s
        while True:
            d.alive()
            n = rows(state, "SELECT COUNT(*) FROM decisions d JOIN notices n USING(notice_id)"
                            " WHERE n.origin LIKE 'kafka:%'")[0][0] if state.exists() else 0
            open_jobs = rows(state, "SELECT COUNT(*) FROM jobs WHERE status IN ('pending','running')")[0][0] \
                if state.exists() else 1
            if n >= produced[0] and open_jobs == 0:
                return
            if time.monotonic() > end:
                raise SystemExit(f"daemon did not decide {produced[0]} notices:\n{d.text()[-3000:]}")
            time.sleep(0.2)

    t = datetime.now(timezone.utc).replace(microsecond=0) - timedelta(hours=2)
    A, B = sha_of(MAP_A), sha_of(MAP_B)
    seqs = []  # (label, sid, [(what, partition)], expectation)
    day = time.strftime("%y%m%d", time.gmtime())

    # a. RETRACTION, then a PRELIMINARY created 300 s earlier arriving late
    sid = f"MS{day}oa"
    ps = [("RETRACTION t", send(notice("RETRACTION", sid, t))),
          ("PRELIMINARY t-300 (late)", send(notice("PRELIMINARY", sid, t - timedelta(seconds=300))))]
    seqs.append(("a", sid, ps, {"planned": False}))
    # b. UPDATE (A), then an older PRELIMINARY with map B
    sid = f"MS{day}ob"
    ps = [("UPDATE t+120 map A", send(notice("UPDATE", sid, t + timedelta(seconds=120), MAP_A))),
          ("PRELIMINARY t map B (late)", send(notice("PRELIMINARY", sid, t, MAP_B)))]
    seqs.append(("b", sid, ps, {"planned": True, "map": A}))
    # c. PRELIMINARY -> RETRACTION -> INITIAL created before the retraction
    sid = f"MS{day}oc"
    ps = [("PRELIMINARY t map A", send(notice("PRELIMINARY", sid, t))),
          ("RETRACTION t+3600", send(notice("RETRACTION", sid, t + timedelta(seconds=3600)))),
          ("INITIAL t+120 map A (late)", send(notice("INITIAL", sid, t + timedelta(seconds=120))))]
    seqs.append(("c", sid, ps, {"planned": False, "withdrawn": True}))
    # d. PRELIMINARY (A), then an EARLYWARNING (B) created 200 s before it
    sid = f"MS{day}od"
    ps = [("PRELIMINARY t map A", send(notice("PRELIMINARY", sid, t))),
          ("EARLYWARNING t-200 map B (late)", send(notice("EARLYWARNING", sid, t - timedelta(seconds=200), MAP_B)))]
    seqs.append(("d", sid, ps, {"planned": True, "map": A}))
    # e. three notices of one event at once, newest first, three partitions
    sid = f"MS{day}oe"
    ps = [("UPDATE t+120 map A", send(notice("UPDATE", sid, t + timedelta(seconds=120), MAP_A), wait=False)),
          ("PRELIMINARY t map B", send(notice("PRELIMINARY", sid, t, MAP_B), wait=False)),
          ("EARLYWARNING t-200 map B", send(notice("EARLYWARNING", sid, t - timedelta(seconds=200), MAP_B),
                                            wait=False))]
    settle()
    seqs.append(("e", sid, ps, {"planned": True, "map": A}))
    # f. a retraction first, then three older notices at once on three partitions
    sid = f"MS{day}of"
    ps = [("RETRACTION t+3600", send(notice("RETRACTION", sid, t + timedelta(seconds=3600)), wait=False)),
          ("UPDATE t+120 map A", send(notice("UPDATE", sid, t + timedelta(seconds=120), MAP_A), wait=False)),
          ("PRELIMINARY t map B", send(notice("PRELIMINARY", sid, t, MAP_B), wait=False)),
          ("EARLYWARNING t-200 map B", send(notice("EARLYWARNING", sid, t - timedelta(seconds=200), MAP_B),
                                            wait=False))]
    settle()
    seqs.append(("f", sid, ps, {"planned": False}))

    msgs = reader.drain(5.0)  # the outbox drains asynchronously
    reader.close()
    rc = d.stop()
    load1 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()

    lines = [f"# benchmarks/attacks/order_attack.py {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC",
             f"# command: PYTHONPATH=$PWD nice -n 5 python benchmarks/attacks/order_attack.py --tree {a.tree} --label '{a.label}'",
             f"# uptime before: {load0}", f"# uptime after:  {load1}",
             f"# input topic {topic}: {nparts} partitions (mock cluster), daemon exit {rc}",
             f"# map A sha256 {A[:12]} ({MAP_A}), map B sha256 {B[:12]} ({MAP_B})", ""]
    verdicts = []
    for label, sid, ps, want in seqs:
        lines.append(f"## {label}: {sid}")
        lines.append("arrival order (partition): " + "; ".join(f"{w} (p{p})" for w, p in ps))
        dec = rows(state, "SELECT n.alert_type, n.time_created, n.origin, d.decision, d.reason FROM decisions d"
                          " JOIN notices n USING(notice_id) WHERE n.superevent_id=? ORDER BY d.decision_id", sid)
        lines.append("decisions stored (in decision order):")
        for at, tc, origin, dd, reason in dec:
            lines.append(f"  {at:12s} created {tc}  {origin.rsplit(':', 2)[-2:]}  -> {dd}: {reason}")
        mine = [m for m in msgs if ((m.get("event") or {}).get("superevent_id") or m.get("superevent_id")) == sid]
        lines.append("published on the outbound topic:")
        for m in mine:
            shas = sorted(set(find_sha(m)))
            lines.append(f"  type={m.get('type')} plan_id={m.get('plan_id')} revision={m.get('revision')} "
                         f"final={m.get('final')} supersedes={m.get('supersedes')} "
                         f"withdrawn={m.get('plan_ids') or m.get('withdrawn')} map={[s[:12] for s in shas]}")
        live = rows(state, "SELECT plan_id, document FROM plans WHERE superevent_id=? AND withdrawn=0 ORDER BY seq",
                    sid)
        wd = rows(state, "SELECT COUNT(*) FROM plans WHERE superevent_id=? AND withdrawn=1", sid)[0][0]
        last_live_map = sorted(set(find_sha(json.loads(live[-1][1]))))[:1] if live else []
        plan_msgs = [m for m in mine if m.get("type") == "plan"]
        last_pub = plan_msgs[-1] if plan_msgs else None
        last_is_withdrawal = bool(mine) and mine[-1].get("type") == "withdrawal"
        if want["planned"]:
            ok = bool(live) and last_live_map == [want["map"]] and last_pub is not None \
                and want["map"] in find_sha(last_pub) and not last_is_withdrawal
            expect = f"a live plan on map {want['map'][:12]} (the newest notice's) stays"
        else:
            ok = not live and (not plan_msgs or last_is_withdrawal)
            if want.get("withdrawn"):
                ok = ok and wd >= 1 and last_is_withdrawal
            expect = "no live plan (retracted stays withdrawn / never planned)"
        lines.append(f"stored live plans: {[p for p, _ in live]} on map {[s[:12] for s in last_live_map]}; "
                     f"withdrawn plans: {wd}")
        lines.append(f"creation order demands: {expect} -> {'OK' if ok else 'WRONG'}")
        lines.append("")
        verdicts.append((label, ok))
    text_log = d.text()
    lines.append(f"summary: {sum(ok for _, ok in verdicts)}/{len(verdicts)} sequences end as creation order "
                 f"demands; tracebacks in the daemon log: {text_log.count('Traceback')}")
    text = "\n".join(lines) + "\n"
    print(text)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(text)
    (Path(a.out).with_suffix(".daemon.log")).write_text(text_log)
    return 0 if all(ok for _, ok in verdicts) else 1


if __name__ == "__main__":
    sys.exit(main())
