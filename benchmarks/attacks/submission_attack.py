"""The submission and service scenarios under attack, end to end on loopback (not in the default test run).

``python benchmarks/attacks/submission_attack.py metrics``: a planning process in a
pids cgroup at the unit's ``TasksMax=256`` (cgroup v1 ``pids``, when this
machine lets us make one) serves ``/metrics``; another process holds 300
idle connections to it while it plans three events; it must plan all three
and still answer a scrape.

``... drip``: Kowalski answers the first event's PUT one byte per second; the
second and third events' queues must still arrive in the same pass.

``... kills``: a submitter process (queue sets of K = 3, every request
answered after 0.3 s) is killed with SIGKILL at 10 random moments and
restarted; then one event is retracted; at the end no queue was accepted
twice, every event's latest set is queued exactly, none orphaned, none left
for the retracted event.

Each prints one JSON line of what it measured.
"""

from __future__ import annotations

import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests" / "daemon"), str(ROOT / "tests")]

TOKEN = "s3cr3t-token-0123456789abcdef"
CGROUP = Path("/sys/fs/cgroup/pids/mushrooms_submission_attack")


def _config(url: str, **submit):
    from mushrooms.daemon.submission.settings import SubmitConfig
    from mushrooms.handlers.policy import PolicyConfig
    from mushrooms.scheduler_core import PlanningConfig
    from mushrooms.scheduler_core.plan.exports import ExportConfig
    from mushrooms.tool.config import Config

    return Config(scheduler=PlanningConfig(solver="greedy", nside=64, time_step_s=600.0, min_gain=0.0,
                                           min_coverage=0.0),
                  policy=PolicyConfig(allow_mock=True, max_notice_age_s=0, max_event_age_s=0),
                  export=ExportConfig(skyportal_allocation_id=7),
                  submit=SubmitConfig(target="kowalski", url=url, timeout_s=submit.pop("timeout_s", 2.0),
                                      retry_initial_s=0.05, retry_max_s=0.2, **submit))


def _pipeline(path: Path, url: str):
    from mushrooms.daemon.intake.pipeline import NoticePipeline
    from mushrooms.daemon.sinks import MemorySink
    from mushrooms.daemon.state.store import Store

    store = Store(path)
    return store, NoticePipeline.from_config(_config(url), store, MemorySink())


def _notice(pipeline, name: str, sid: str, created: str | None = None) -> str:
    from daemon_helpers import notice_bytes

    return pipeline.handle(notice_bytes(name, sid, created), f"bench:{name}").decision


# ---------------------------------------------------------------- metrics
def metrics_child(state: str, port_file: str) -> None:
    """The daemon side: listener + planning of three events once told to (stdin line)."""
    from mushrooms.daemon.ops.health import HealthServer
    from mushrooms.daemon.ops.metrics import ServiceMetrics

    store, pipeline = _pipeline(Path(state), "http://127.0.0.1:9")
    listener = HealthServer("127.0.0.1", 0, ServiceMetrics("0", Path(state)), lambda: (True, {})).start()
    Path(port_file).write_text(str(listener.address[1]))
    sys.stdin.readline()
    decisions = [_notice(pipeline, "MS181101ab-preliminary.json", sid) for sid in ("S1", "S2", "S3")]
    print(json.dumps({"decisions": decisions, "threads": threading.active_count()}), flush=True)
    sys.stdin.readline()


def metrics() -> dict:
    tmp = Path(tempfile.mkdtemp())
    cgroup = None
    try:
        CGROUP.mkdir(exist_ok=True)
        (CGROUP / "pids.max").write_text("256")
        cgroup = CGROUP
    except OSError as exc:
        cgroup_error = str(exc)
    child = subprocess.Popen([sys.executable, __file__, "metrics-child", str(tmp / "s.sqlite"), str(tmp / "port")],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    if cgroup is not None:
        (cgroup / "cgroup.procs").write_text(str(child.pid))
    for _ in range(600):
        if (tmp / "port").exists() and (tmp / "port").read_text():
            break
        time.sleep(0.1)
    port = int((tmp / "port").read_text())
    t0 = time.time()
    idle = []
    for _ in range(300):
        try:
            idle.append(socket.create_connection(("127.0.0.1", port), timeout=5))
        except OSError:
            pass
    connect_s = time.time() - t0
    peak_during_idle = int((cgroup / "pids.current").read_text()) if cgroup else None
    child.stdin.write("plan\n")
    child.stdin.flush()
    planned = json.loads(child.stdout.readline())
    scraped, tries, t_scrape = None, 0, time.time()
    while scraped is None and time.time() - t_scrape < 60:  # the 16 served idle ones time out after 10 s
        tries += 1
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=30) as r:
                scraped = r.status
        except OSError:
            time.sleep(1.0)
    scrape_wait_s = round(time.time() - t_scrape, 1)
    peak = int((cgroup / "pids.peak").read_text()) if cgroup and (cgroup / "pids.peak").exists() else None
    events = (cgroup / "pids.events").read_text().strip() if cgroup else None
    for s in idle:
        s.close()
    child.stdin.write("done\n")
    child.stdin.flush()
    child.wait(30)
    if cgroup is not None:
        CGROUP.rmdir()
    return {"scenario": "metrics", "idle_connections": len(idle), "connect_s": round(connect_s, 1),
            "cgroup": str(cgroup) if cgroup else f"none ({cgroup_error})", "pids_max": 256 if cgroup else None,
            "pids_during_idle": peak_during_idle, "pids_peak": peak, "pids_events": events,
            "decisions": planned["decisions"], "child_threads_after_planning": planned["threads"],
            "scrape_status": scraped, "scrape_tries": tries, "scrape_wait_s": scrape_wait_s,
            "note": "the 300 idle connections stay open while planning and scraping"}


# ---------------------------------------------------------------- drip
def drip() -> dict:
    from contract_servers import KowalskiContract, loopback_server
    from mushrooms.daemon.submission.remote import make_client
    from mushrooms.daemon.submission.submitter import Submitter, submissions

    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    tmp = Path(tempfile.mkdtemp())
    store, pipeline = _pipeline(tmp / "s.sqlite", kowalski.url)
    config = _config(kowalski.url, timeout_s=5.0)
    for sid in ("S1", "S2", "S3"):
        _notice(pipeline, "MS181101ab-preliminary.json", sid)
    kowalski.drip_s, kowalski.hang_s = 1.0, 120.0  # 1 byte/s for two minutes
    kowalski.faults["PUT"] = ["drip"]
    submitter = Submitter(store, config.submit, config.export, make_client("kowalski", kowalski.url, TOKEN, 5.0))
    t0 = time.time()
    waiting = submitter.step()
    pass_s = time.time() - t0
    rows = {s.superevent_id: (s.state, (s.answer or "")[:80]) for s in submissions(store)}
    queued = sorted(kowalski.queues)
    t1 = time.time()
    while submitter.step():
        time.sleep(0.1)
    out = {"scenario": "drip", "drip_bytes_per_s": 1, "timeout_s": 5.0, "first_pass_s": round(pass_s, 2),
           "first_pass_waiting": waiting, "rows_after_first_pass": rows, "queued_after_first_pass": queued,
           "all_queued_after_s": round(time.time() - t1, 2), "queued_at_end": sorted(kowalski.queues)}
    store.close()
    server.stop()
    return out


# ---------------------------------------------------------------- kills
def kills_child(state: str, url: str) -> None:
    """A submitter that runs passes until nothing is open (then exits 0)."""
    from mushrooms.daemon.submission.remote import make_client
    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.submission.submitter import Submitter
    from mushrooms.scheduler_core.plan import exports
    from test_submission_sets import three_queues

    exports.to_trigger_queues = three_queues
    config = _config(url, timeout_s=5.0)
    store = Store(Path(state))
    submitter = Submitter(store, config.submit, config.export, make_client("kowalski", url, TOKEN, 5.0))
    while submitter.step() or _has_pending(store):
        time.sleep(0.05)
    store.close()


def _has_pending(store) -> bool:
    return bool(store.connection().execute("SELECT COUNT(*) FROM submissions WHERE state='pending'").fetchone()[0])


def kills(n_kills: int = 10, seed: int = 7) -> dict:
    from contract_servers import KowalskiContract, loopback_server
    from mushrooms.daemon.submission.submitter import submissions

    rng = random.Random(seed)
    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    kowalski.delay_s = 0.3
    tmp = Path(tempfile.mkdtemp())
    state = tmp / "s.sqlite"
    store, pipeline = _pipeline(state, kowalski.url)
    _notice(pipeline, "MS181101ab-preliminary.json", "S1")
    _notice(pipeline, "MS181101ab-preliminary.json", "S2")
    _notice(pipeline, "MS181101ab-preliminary.json", "S3")
    cmd = [sys.executable, __file__, "kills-child", str(state), kowalski.url]
    killed_at, decisions = [], []
    for i in range(n_kills):
        child = subprocess.Popen(cmd)
        wait = rng.uniform(0.5, 3.0)
        time.sleep(wait)
        if child.poll() is None:
            os.kill(child.pid, signal.SIGKILL)
            child.wait()
            killed_at.append(round(wait, 2))
        if i == 2:  # an updated map: S1's r2 set replaces r1's while the kills go on
            decisions.append(_notice(pipeline, "MS230425l-preliminary.json", "S1"))
        if i == n_kills // 2:  # S2 retracted: every queue of every revision goes
            decisions.append(_notice(pipeline, "MS181101ab-retraction.json", "S2"))
    child = subprocess.Popen(cmd)
    rc = child.wait(300)
    accepted = [e["queue_name"] for e in kowalski.log if e["method"] == "PUT" and e["status"] == 200]
    rows = [(s.superevent_id, s.revision, s.state) for s in submissions(store)]
    queued = sorted(kowalski.queues)
    expected = sorted(f"ToO_GW_{sid}_r{r}_{k}" for sid, r, st in rows if st == "submitted" and r
                      for k in (1, 2, 3))
    out = {"scenario": "kills", "decisions_during_kills": decisions, "kills": len(killed_at), "killed_after_s": killed_at, "final_rc": rc,
           "requests": len(kowalski.log), "accepted_puts": len(accepted),
           "accepted_twice": sorted({n for n in accepted if accepted.count(n) > 1}),
           "rows": rows, "queued": queued, "queued_is_the_submitted_sets": queued == expected,
           "queued_for_retracted_S2": [n for n in queued if "_S2_" in n],
           "orphans": sorted(set(queued) - set(expected))}
    store.close()
    server.stop()
    return out


if __name__ == "__main__":
    what = sys.argv[1]
    if what == "metrics-child":
        metrics_child(*sys.argv[2:4])
    elif what == "kills-child":
        kills_child(*sys.argv[2:4])
    else:
        print(json.dumps({"metrics": metrics, "drip": drip, "kills": kills}[what]()))
