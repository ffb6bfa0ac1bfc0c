"""A state file with WINTER parts, and a SkyPortal that stores what it refuses (``[submit_parts]``, issue 53).

The parts are the service's own rows (``telescope_parts``) and files
(``skyportal_request.json`` written by :func:`part_request` from a real WINTER
plan, ``data/winter_part_plan.json``: MS181101ab planned by the service with
``telescopes = ["ztf", "winter"]``); :class:`PartsSkyPortal` adds to
``contract_servers.SkyPortalContract`` the event's request list (``GET
/api/observation_plan?dateobs=``) and SkyPortal's habit of storing a manual
request before it checks its filters (observation_plan.py lines 1430-1472).
"""

from __future__ import annotations

import datetime as dt
import json
import threading
from pathlib import Path
from typing import Any

from werkzeug import Request, Response

from contract_servers import SkyPortalContract, _error, _json

DATA = Path(__file__).resolve().parent / "data"
TOKEN = "parts-s3cr3t-token-9f8e7d6c5b4a"
SID = "MS181101ab"


def winter_plan() -> dict[str, Any]:
    return json.loads((DATA / "winter_part_plan.json").read_text())


def plan_start() -> dt.datetime:
    """When the WINTER plan starts (the tests' "now")."""
    return dt.datetime.fromisoformat(winter_plan()["start"].rstrip("Z")).replace(tzinfo=dt.timezone.utc)


def parts_state(tmp_path: Path, jobs: list[tuple[int, str, str]], retracted: bool = False) -> Path:
    """A state file whose jobs ``(job_id, alert_type, part state)`` each have an exported WINTER part."""
    from mushrooms.daemon.state.parts import record_part
    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.submission.part_request import part_request
    from mushrooms.scheduler_core.instruments import load_description
    from mushrooms.scheduler_core.plan.document import Plan

    path = tmp_path / "state.sqlite"
    store = Store(path)
    winter = load_description("winter")
    now = "2026-12-06T20:00:00Z"
    try:
        with store.transaction() as c:
            c.execute("INSERT INTO events(superevent_id, updated_at, retracted) VALUES (?,?,?)",
                      (SID, now, int(retracted)))
            for job_id, alert_type, state in jobs:
                c.execute("INSERT INTO notices(notice_id, received_at, origin, sha256, size, superevent_id, alert_type)"
                          " VALUES (?,?,?,?,?,?,?)", (job_id, now, "test", "0" * 64, 1, SID, alert_type))
                c.execute("INSERT INTO jobs(job_id, notice_id, superevent_id, alert_type, skymap_sha256, decision,"
                          " start, received_wall, status, created_at) VALUES (?,?,?,?,?,?,?,?,?,?)",
                          (job_id, job_id, SID, alert_type, f"{job_id:064d}", "plan", now, 0.0, "done", now))
        for job_id, alert_type, state in jobs:
            doc = winter_plan()
            doc["plan_id"] = f"mushrooms-{job_id:04x}{'c' * 12}"  # each job's own plan (and request name)
            plan = Plan.from_document(doc)
            folder = tmp_path / "outbox" / "telescopes" / SID / f"{job_id:05d}-{alert_type}" / "winter"
            folder.mkdir(parents=True)
            (folder / "skyportal_request.json").write_text(json.dumps(part_request(plan, winter)))
            record_part(store, job_id, "winter", SID, "skyportal", "exported", plan.plan_id, str(folder))
            if state != "exported":
                with store.transaction() as c:
                    c.execute("UPDATE telescope_parts SET state=? WHERE job_id=?", (state, job_id))
    finally:
        store.close()
    return path


def sender(state: Path, url: str, token: str | None = TOKEN, **settings: Any) -> tuple[Any, Any]:
    """(PartSender, store) on ``state`` against ``url``: the daemon's own classes (a new one is a restart)."""
    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.submission.parts_sender import PartSender
    from mushrooms.daemon.submission.parts_settings import PartSubmitConfig
    from mushrooms.daemon.submission.remote import SkyPortalPlans

    config = PartSubmitConfig.from_mapping({"enabled": True, "url": url, "allocations": {"winter": 7},
                                            "timeout_s": 2.0, **settings})
    store = Store(state)
    return PartSender(store, config, SkyPortalPlans(url, token, config.timeout_s)), store


def rows(state: Path) -> list[dict[str, Any]]:
    import sqlite3

    conn = sqlite3.connect(state)
    conn.row_factory = sqlite3.Row
    try:
        return [dict(r) for r in conn.execute("SELECT * FROM part_requests ORDER BY job_id")]
    finally:
        conn.close()


class PartsSkyPortal(SkyPortalContract):
    """SkyPortal with an instrument whose filters are ``filters``; lists an event's requests; keeps refused ones."""

    def __init__(self, server: Any, token: str = TOKEN, filters: tuple[str, ...] = ("desy", "2massj", "2massh")) -> None:
        super().__init__(server, token)
        self.filters = set(filters)
        self.undeletable = False  # "Cannot delete observation plans on this instrument."
        self.on_post: Any = None  # called with the stored id before a POST is answered (a kill -9 there)
        self.huge_next = False  # answer the next POST with 5 MB after storing it
        self._ids = threading.Lock()
        server.expect_request("/api/observation_plan", method="GET").respond_with_handler(self._handle)

    def _apply(self, request: Request, body: Any) -> Response:
        if request.method == "GET" and request.path == "/api/observation_plan":
            listed = [{"id": pid, "payload": p["payload"], "status": "complete", "allocation_id": p["allocation_id"]}
                      for pid, p in sorted(self.plans.items()) if p["dateobs"] == request.args.get("dateobs")]
            page, n = int(request.args.get("pageNumber", 1)), int(request.args.get("numPerPage", 100))
            return _json(200, {"status": "success", "data": {"requests": listed[(page - 1) * n:page * n],
                                                               "totalMatches": len(listed)}})
        if request.method == "DELETE" and self.undeletable:
            return _error("Cannot delete observation plans on this instrument.")
        if request.method != "POST":
            return super()._apply(request, body)
        return self._post(body)

    def _post(self, body: Any) -> Response:
        if not isinstance(body, dict) or "observation_plans" not in body or "plan_name" not in body:
            return _error("KeyError: 'observation_plans'")
        with self._ids:  # stored first, checked after (as SkyPortal does)
            pid, self._next = self._next, self._next + 1
            self.plans[pid] = body
        planned = body["observation_plans"][0]["planned_observations"]
        if not {o["filt"] for o in planned} <= self.filters:
            return _error(f"Planned observation filter(s) not in instrument's filter list, must be one of: "
                          f"{sorted(self.filters)}")
        if self.on_post is not None:
            self.on_post(pid)
        if self.huge_next:
            self.huge_next = False
            return Response(b"{" + b" " * (5 * 2**20) + b"}", status=200, content_type="application/json")
        return _json(200, {"status": "success", "data": {"id": pid}})

    def posts(self) -> list[dict[str, Any]]:
        return [e for e in self.log if e["method"] == "POST"]


def round_two(tmp_path: Path, state: Path, job_id: int = 1, alert_type: str = "PRELIMINARY") -> tuple[str, str]:
    """Re-plan job ``job_id``'s WINTER part around ZTF's revision 2 as the service does (issue 53 J9).

    :func:`~mushrooms.daemon.state.parts.record_part` with ``round_=2``: the
    job's ``telescope_parts`` row is replaced (same job, telescope; new plan id,
    folder ``<job>-<type>-round2/``) and round 1's folder marked ``SUPERSEDED``.
    Round 2's (plan id, SkyPortal plan name).
    """
    from mushrooms.daemon.state.parts import record_part
    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.submission.part_request import part_request
    from mushrooms.scheduler_core.instruments import load_description
    from mushrooms.scheduler_core.plan.document import Plan

    doc = winter_plan()
    doc["plan_id"] = f"mushrooms-{job_id:04x}{'d' * 12}"  # round 2's own plan (and request name)
    plan = Plan.from_document(doc)
    job = tmp_path / "outbox" / "telescopes" / SID
    folder = job / f"{job_id:05d}-{alert_type}-round2" / "winter"
    folder.mkdir(parents=True)
    request = part_request(plan, load_description("winter"))
    (folder / "skyportal_request.json").write_text(json.dumps(request))
    (job / f"{job_id:05d}-{alert_type}" / "winter" / "SUPERSEDED").write_text("round 2\n")
    store = Store(state)
    try:
        assert record_part(store, job_id, "winter", SID, "skyportal", "exported", plan.plan_id, str(folder),
                           round_=2, held="revision-2")
    finally:
        store.close()
    return plan.plan_id, request["plan_name"]


def send_killed_at_the_post(state: Path, skyportal: Any) -> tuple[int, bytes, bytes]:
    """One sender pass in a child process, killed with SIGKILL while SkyPortal answers its POST.

    Returns the child's exit status, stdout and stderr; ``skyportal.on_post`` is cleared after.
    """
    import os
    import signal
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    child: list[subprocess.Popen] = []
    skyportal.on_post = lambda pid: (os.kill(child[0].pid, signal.SIGKILL), child[0].wait(30))
    script = ("import sys; sys.path[:0] = [sys.argv[1], sys.argv[2]];"
              "from part_requests_setup import sender, plan_start;"
              "s, store = sender(sys.argv[3], sys.argv[4]); s.step(now=plan_start()); print('not killed')")
    child.append(subprocess.Popen([sys.executable, "-c", script, str(root), str(Path(__file__).parent), str(state),
                                   skyportal.url], stdout=subprocess.PIPE, stderr=subprocess.PIPE))
    out, err = child[0].communicate(timeout=120)
    skyportal.on_post = None
    return child[0].returncode, out, err
