#!/usr/bin/env python
"""Queue sets through the real daemon and the Kowalski contract server: the request log.

``mushrooms run`` (a subprocess, greedy at nside 64 as the daemon tests run
it) reads notices from the loopback Kafka broker (librdkafka's mock cluster)
and submits each revision's queue set (``to_trigger_queues``) to the
Kowalski contract server of ``tests/daemon/contract_servers.py``:

1. ``lifecycle``: a notice -> its set PUT; an updated sky map -> the new set
   PUT, then the old set DELETEd; a retraction -> every queue DELETEd.
2. ``kill``: the daemon kills itself with SIGKILL right after the first PUT
   of a set is answered (``tests/daemon/submit_fault_run.py after_put``,
   before the set's second PUT); a fresh daemon on the same state file
   finishes the set: no queue accepted twice, none orphaned.

Writes the request log (every request in order, with the queue it names and
the server's status) to ``benchmarks/results/execution/queue_execution/daemon_request_log.txt``
and prints one JSON line per scenario.

    PYTHONPATH=. nice .venv/bin/python benchmarks/loop/daemon_queue_sets.py
"""

from __future__ import annotations

import json
import sqlite3
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests" / "daemon"), str(ROOT / "tests")]

from contract_servers import KowalskiContract, loopback_server  # noqa: E402
from daemon_helpers import Broker, Daemon, notice_bytes, write_config  # noqa: E402

TOKEN = "bench-s3cr3t-0a1b2c3d4e5f"
SID = "MS181101ab"
FAULT_RUN = ROOT / "tests" / "daemon" / "submit_fault_run.py"
OUT = ROOT / "benchmarks" / "results" / "execution" / "queue_execution" / "daemon_request_log.txt"


class World:
    """One daemon setup: topics on the broker, a config, a state file, the contract server."""

    def __init__(self, broker: Broker, tmp: Path, kowalski: KowalskiContract) -> None:
        self.broker, self.tmp, self.kowalski = broker, tmp, kowalski
        stamp = time.time_ns()
        self.topic, out, group = f"gwalert-{stamp}", f"plans-{stamp}", f"mushrooms-{stamp}"
        broker.ensure_topic(self.topic)
        broker.ensure_topic(out)
        extra = (f'\n[submit]\ntarget = "kowalski"\nurl = "{kowalski.url}"\ntimeout_s = 3.0\n'
                 "retry_initial_s = 0.5\nretry_max_s = 2.0\n")
        self.cfg = write_config(tmp / "config.toml", self.topic, out, group, extra)
        self.state = tmp / "state.sqlite"
        self.args = ["--config", str(self.cfg), "--bootstrap", broker.bootstrap, "--state", str(self.state)]

    def daemon(self, kill_point: str | None = None) -> Daemon:
        env = {"MUSHROOMS_SUBMIT_TOKEN": TOKEN}
        if kill_point:
            env["MUSHROOMS_TEST_SUBMIT_KILL"] = kill_point
        return Daemon(self.tmp, self.args, env=env, wrapper=FAULT_RUN if kill_point else None)

    def send(self, name: str, sid: str, created: str | None = None) -> None:
        self.broker.produce(self.topic, notice_bytes(name, sid, created), key=sid.encode())

    def states(self) -> list[tuple]:
        with sqlite3.connect(self.state) as c:
            return c.execute("SELECT revision, queue_name, state FROM submissions WHERE superevent_id=? "
                             "ORDER BY revision", (SID,)).fetchall()


def revisions(kowalski: KowalskiContract) -> list[int]:
    base = f"ToO_GW_{SID}_r"
    return sorted({int(n[len(base):].split("_")[0]) for n in list(kowalski.queues) if n.startswith(base)})


def wait(predicate, timeout_s: float, d: Daemon, what: str) -> None:
    end = time.monotonic() + timeout_s
    while not predicate():
        if d.proc.poll() is not None and d.proc.returncode != 0:
            raise SystemExit(f"daemon died waiting for {what}:\n{d.text()[-3000:]}")
        if time.monotonic() > end:
            raise SystemExit(f"timed out waiting for {what}:\n{d.text()[-3000:]}")
        time.sleep(0.1)


def log_lines(kowalski: KowalskiContract, t0: float) -> list[str]:
    return [f"{e['t'] - t0:8.2f} s  {e['method']:6s} {e['path']} {e.get('queue_name') or ''} -> {e['status']}"
            for e in kowalski.log]


def accepted_twice(kowalski: KowalskiContract) -> list[str]:
    puts = [e["queue_name"] for e in kowalski.log if e["method"] == "PUT" and e["status"] == 200]
    return sorted({n for n in puts if puts.count(n) > 1})


def lifecycle(broker: Broker, tmp: Path) -> tuple[dict, list[str]]:
    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    w = World(broker, tmp, kowalski)
    t0 = time.time()
    d = w.daemon()
    d.wait_log("event=service_ready", 180)
    w.send("MS181101ab-preliminary.json", SID)
    wait(lambda: revisions(kowalski) == [1] and w.states()[-1][2] == "submitted", 300, d, "revision 1's set")
    k1 = len(kowalski.queues)
    w.send("MS230425l-preliminary.json", SID)  # an updated sky map of the same event
    wait(lambda: revisions(kowalski) == [2] and w.states()[-1][2] == "submitted", 300, d, "revision 2 replacing 1")
    k2 = len(kowalski.queues)
    w.send("MS181101ab-retraction.json", SID, "2023-04-26T00:00:00Z")
    wait(lambda: not kowalski.queues and w.states()[-1][2] == "deleted", 300, d, "the retraction's DELETEs")
    rc = d.stop()
    steps = []  # (method, revision) runs, in order
    for e in kowalski.log:
        if e["method"] in ("PUT", "DELETE"):
            step = (e["method"], int(str(e["queue_name"]).split("_r")[-1].split("_")[0]))
            if not steps or steps[-1] != step:
                steps.append(step)
    out = {"scenario": "lifecycle", "queues_r1": k1, "queues_r2": k2, "requests": len(kowalski.log),
           "order": [f"{m} r{r}" for m, r in steps], "all_200": all(e["status"] == 200 for e in kowalski.log),
           "accepted_twice": accepted_twice(kowalski), "left_on_server": sorted(kowalski.queues),
           "states": w.states(), "daemon_rc": rc}
    lines = log_lines(kowalski, t0)
    server.stop()
    return out, lines


def kill(broker: Broker, tmp: Path) -> tuple[dict, list[str]]:
    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    w = World(broker, tmp, kowalski)
    t0 = time.time()
    d1 = w.daemon(kill_point="after_put")
    d1.wait_log("event=service_ready", 180)
    w.send("MS181101ab-preliminary.json", SID)
    d1.proc.wait(600)
    on_server_at_kill = sorted(kowalski.queues)
    d2 = w.daemon()
    wait(lambda: bool(w.states()) and w.states()[-1][2] == "submitted", 300, d2, "the restart to finish the set")
    rc = d2.stop()
    with sqlite3.connect(w.state) as c:
        body = c.execute("SELECT body FROM submissions WHERE superevent_id=? ORDER BY revision DESC",
                         (SID,)).fetchone()
    sent = json.loads(body[0]) if body and body[0] else []
    names = [str(q["queue_name"]) for q in sent] if isinstance(sent, list) else []
    queued = sorted(kowalski.queues)
    out = {"scenario": "kill", "killed_rc": d1.proc.returncode, "on_server_at_kill": on_server_at_kill,
           "after_restart": queued, "set_size": len(queued), "requests": len(kowalski.log),
           "accepted_twice": accepted_twice(kowalski),
           "orphans": sorted(set(queued) - set(names)), "missing": sorted(set(names) - set(queued)),
           "states": w.states(), "daemon_rc": rc}
    lines = log_lines(kowalski, t0)
    server.stop()
    return out, lines


def main() -> int:
    broker = Broker()
    report = []
    for name, scenario in (("lifecycle", lifecycle), ("kill", kill)):
        with tempfile.TemporaryDirectory() as tmp:
            out, lines = scenario(broker, Path(tmp))
        print(json.dumps(out, default=str), flush=True)
        report += [f"== {name}: {json.dumps(out, default=str)}", *lines, ""]
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(report) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
