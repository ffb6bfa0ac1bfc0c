"""A part re-planned around ZTF's revision 2 is sent, and round 1's request is then taken back (issue 53, J9).

coord53 re-plans a job's other-telescope parts around ZTF's revision 2 into
``<job>-<type>-round2/`` and replaces the job's ``telescope_parts`` row (same
job, telescope; new plan id, round 2).  ``[submit_parts]`` must POST round 2's
request, then DELETE round 1's, never both DELETEd and nothing POSTed twice,
whatever a kill -9 or a 5xx does in between.  Against the SkyPortal contract
server on loopback (pytest-httpserver), the service's own state functions.
"""

from __future__ import annotations

import signal
import sqlite3
from pathlib import Path

import pytest

from part_requests_setup import send_killed_at_the_post, PartsSkyPortal, parts_state, plan_start, round_two, sender



@pytest.fixture
def skyportal(loopback):
    return PartsSkyPortal(loopback)


def _step(state: Path, url: str) -> int:
    """One pass of a freshly opened sender (a restart), at the plan's start."""
    s, store = sender(state, url)
    try:
        return s.step(now=plan_start())
    finally:
        store.close()


def _names(skyportal) -> list[str]:
    """The plan names SkyPortal holds."""
    return sorted(p["plan_name"] for p in skyportal.plans.values())


def _requests(state: Path) -> list[tuple[str, str]]:
    """(plan id, state) of every request row, by plan id."""
    with sqlite3.connect(state) as c:
        return sorted(c.execute("SELECT plan_id, state FROM part_requests").fetchall())


def _calls(skyportal) -> list[tuple[str, str, str]]:
    """(method, path, plan name) of the POSTs and DELETEs SkyPortal answered 200."""
    return [(e["method"], e["path"], e.get("plan_name", "")) for e in skyportal.log
            if e["method"] in ("POST", "DELETE") and e["status"] == 200]


def test_round_two_is_posted_then_round_one_deleted(tmp_path, skyportal, capsys):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    (first,) = _names(skyportal)
    second_plan, second_name = round_two(tmp_path, state)
    skyportal.faults["POST"] = ["503"]  # round 2's first POST unanswered: round 1's request must stay
    assert _step(state, skyportal.url) == 1
    assert _names(skyportal) == [first] and not [c for c in _calls(skyportal) if c[0] == "DELETE"]
    assert _step(state, skyportal.url) == 0
    (second,) = _names(skyportal)
    assert second == second_name != first  # round 2's request stands alone
    calls = _calls(skyportal)
    assert [c[0] for c in calls] == ["POST", "POST", "DELETE"] and calls[2][1] == "/api/observation_plan/1"
    assert [c[2] for c in calls[:2]] == [first, second]  # each POSTed once, round 2's before round 1's DELETE
    assert dict(_requests(state))[second_plan] == "sent" and sorted(s for _, s in _requests(state)) == [
        "replaced", "sent"]
    assert _step(state, skyportal.url) == 0 and _calls(skyportal) == calls  # nothing more
    from mushrooms.tool.status import main

    capsys.readouterr()
    main(["--state", str(state)])  # the part standing is round 2's, and so is the request status names
    out = capsys.readouterr().out
    assert "SkyPortal request sent (id 2)" in out and "(id 1)" not in out, out


def test_a_kill9_during_round_twos_post_keeps_round_one_until_round_two_is_found(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    (first,) = _names(skyportal)
    second_plan, second_name = round_two(tmp_path, state)
    code, out, err = send_killed_at_the_post(state, skyportal)
    assert code == -signal.SIGKILL and b"not killed" not in out, err[-2000:]
    assert len(skyportal.plans) == 2 and first in _names(skyportal)  # round 2 stored, its answer never recorded
    assert not [e for e in skyportal.log if e["method"] == "DELETE"]  # round 1 kept while round 2's fate is unknown
    assert _step(state, skyportal.url) == 0  # the restart: round 2 found by its name, then round 1 DELETEd
    (second,) = _names(skyportal)
    assert second == second_name != first
    assert [e["plan_name"] for e in skyportal.log if e["method"] == "POST"] == [first, second]  # never twice
    assert [e["path"] for e in skyportal.log if e["method"] == "DELETE"] == ["/api/observation_plan/1"]
    assert sorted(s for _, s in _requests(state)) == ["replaced", "sent"]


def test_a_round_one_request_never_sent_is_skipped_and_round_two_sent(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    skyportal.faults["POST"] = ["503"]  # round 1 tried, unanswered, nothing stored
    assert _step(state, skyportal.url) == 1
    second_plan, second_name = round_two(tmp_path, state)
    assert _step(state, skyportal.url) == 0
    (second,) = _names(skyportal)
    assert second == second_name
    assert dict(_requests(state))[second_plan] == "sent" and sorted(s for _, s in _requests(state)) == [
        "sent", "skipped"]
    assert not [e for e in skyportal.log if e["method"] == "DELETE"]


#: main's (b00c596) part_requests, keyed by (job_id, telescope): a state file written this week has it
OLD_TABLE = """CREATE TABLE part_requests (job_id INTEGER NOT NULL, telescope TEXT NOT NULL,
    superevent_id TEXT NOT NULL, plan_id TEXT, plan_name TEXT NOT NULL UNIQUE, state TEXT NOT NULL, reason TEXT,
    body TEXT, remote_id TEXT, http_status INTEGER, answer TEXT, attempts INTEGER NOT NULL DEFAULT 0,
    tried INTEGER NOT NULL DEFAULT 0, created_at TEXT NOT NULL, updated_at TEXT NOT NULL,
    PRIMARY KEY (job_id, telescope));
CREATE INDEX part_requests_state ON part_requests(state);"""


def test_a_state_file_with_mains_request_table_keeps_its_rows_and_sends_round_two(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    with sqlite3.connect(state) as c:  # the table as main wrote it, with the row main recorded
        kept = c.execute("SELECT job_id, telescope, superevent_id, plan_id, plan_name, state, reason, body, remote_id,"
                         " http_status, answer, attempts, tried, created_at, updated_at FROM part_requests").fetchall()
        c.executescript("DROP TABLE part_requests;" + OLD_TABLE)
        c.executemany(f"INSERT INTO part_requests VALUES ({','.join('?' * len(kept[0]))})", kept)
    (first,) = _names(skyportal)
    second_plan, second_name = round_two(tmp_path, state)  # opens the file: the table is brought up to date
    with sqlite3.connect(state) as c:
        c.row_factory = sqlite3.Row
        (row,) = [dict(r) for r in c.execute("SELECT * FROM part_requests")]
    assert row["round"] == 1 and row["state"] == "sent" and row["remote_id"] == "1" and row["plan_name"] == first
    assert _step(state, skyportal.url) == 0
    (second,) = _names(skyportal)
    assert second == second_name and sorted(s for _, s in _requests(state)) == ["replaced", "sent"]


@pytest.mark.slow
def test_the_service_replans_winter_around_ztfs_revision_2_and_the_sender_follows(tmp_path, skyportal):
    """End to end: the daemon's pipeline (ztf + winter) with ZTF's revision 2 forced as test_coordinated_parts forces
    it; the sender runs between the two rounds (round 1 sent) and after (round 2 sent, round 1 DELETEd)."""
    import datetime as dt
    import json

    from test_coordinated_parts import PRELIMINARY, _halved_first_plan, _run, notice_bytes

    from mushrooms.scheduler_core.anytime import FIRST_SOLVER
    from mushrooms.scheduler_core.planner import run_scheduler

    state, outbox = tmp_path / "state.sqlite", tmp_path / "outbox"
    halved, seen = _halved_first_plan(run_scheduler), []

    def when(folder: str) -> dt.datetime:
        (request,) = (outbox / "telescopes").glob(f"*/{folder}/winter/skyportal_request.json")
        start = json.loads(request.read_text())["validity_window_start"]
        return dt.datetime.fromisoformat(str(start).rstrip("Z")).replace(tzinfo=dt.timezone.utc)

    def step(folder: str) -> int:
        s, store = sender(state, skyportal.url)
        try:
            return s.step(now=when(folder))
        finally:
            store.close()

    def scheduler(problem, solver, should_stop=None):
        if solver != FIRST_SOLVER and not seen and list((outbox / "telescopes").glob("*/00001-PRELIMINARY/winter")):
            seen.append(step("00001-PRELIMINARY"))  # round 1 recorded: the sender's thread sends it
        return halved(problem, solver, should_stop)

    (out,) = _run(tmp_path, ["ztf", "winter"], [notice_bytes(PRELIMINARY)], solver="slots", planner=scheduler)
    assert out.revision == 2 and seen == [0] and len(skyportal.plans) == 1  # round 1's request was sent
    (first,) = _names(skyportal)
    assert step("00001-PRELIMINARY-round2") == 0
    (second,) = _names(skyportal)
    request = json.loads(next((outbox / "telescopes").glob("*/00001-PRELIMINARY-round2/winter/"
                                                           "skyportal_request.json")).read_text())
    assert second == request["plan_name"] != first
    calls = _calls(skyportal)
    assert [c[0] for c in calls] == ["POST", "POST", "DELETE"] and [c[2] for c in calls[:2]] == [first, second]
    assert sorted(s for _, s in _requests(state)) == ["replaced", "sent"]
