"""The loop through the real pipeline: executed exposures in, slips and closures re-planned.

A real notice planned by :class:`NoticePipeline` on real SQLite (greedy, real
checker), the executed record written as the JSON-lines file the
:class:`~mushrooms.daemon.loop.poll.ExecutedLoop` polls, and the re-plan made by
the real :func:`~mushrooms.scheduler_core.replan.plan_remaining` in the
pipeline's job.  The poll's clock is the night's (``now=``), so the scenario
is the same on every run.
"""

from __future__ import annotations

import logging
import sqlite3

import pytest

from mushrooms.daemon.state.executed import count_executed
from mushrooms.daemon.planning.replans import replan_jobs
from mushrooms.scheduler_core.executed import done_pairs
from mushrooms.scheduler_core.plan.schema import validate_document

from loop_helpers import (SUPEREVENT, after, copy_state, executed_like, loop_config, open_pipeline, planned_state,
                          poller, t, the_plan, write_executed)

CADENCE_S = 1800.0


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    return planned_state(tmp_path_factory.mktemp("planned"))


@pytest.fixture
def loop(planned, tmp_path):
    """The planned state (a private copy) under a pipeline whose [loop] reads ``tmp_path/executed.jsonl``."""
    executed = tmp_path / "executed.jsonl"
    p = open_pipeline(copy_state(planned, tmp_path), loop_config(executed, max_slip_s=900.0))
    yield p, executed
    p.store.close()


def test_a_closure_of_two_hours_gives_a_revision_from_the_reopening_that_keeps_the_pairs(loop):
    """The issue's must-show: notice -> plan; the first 10 exposures executed; closed 2 h -> a new revision."""
    p, executed = loop
    first = the_plan(p)
    obs = first["observations"]
    ten = executed_like(obs[:10])
    write_executed(executed, ten)
    now = after(obs[9]["end"], 60.0)
    poll = poller(p).poll(now)
    assert (poll.read, poll.stored.added, poll.replans) == (10, 10, [])  # on time: nothing to re-plan
    reopening = after(obs[9]["end"], 7200.0 + 60.0)
    acc = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure", now=now.to_datetime())
    assert acc.action == "replan" and acc.job is not None and acc.job.start.startswith(reopening.isot[:19])
    out = p.run_job(acc.job)
    assert out.decision == "replan" and out.plan_id and out.supersedes == first["plan_id"], out
    new = the_plan(p)
    validate_document(new)
    assert (new["revision"], new["final"], new["supersedes"]) == (2, True, first["plan_id"])
    assert new["plan_id"] != first["plan_id"] and new["observations"]
    assert min(t(o["start"]).unix for o in new["observations"]) >= reopening.unix - 1e-3
    pairs = done_pairs(ten, ("g", "r"), cadence_s=CADENCE_S)
    assert pairs.both and pairs.one  # the scenario has both kinds: 4 completed pairs, 2 fields half done
    assert not [o for o in new["observations"] if o["field_id"] in pairs.both]
    for field_id, visits in pairs.one.items():
        other = {"g": "r", "r": "g"}[visits.filters[0]]
        later = [o for o in new["observations"] if o["field_id"] == field_id and o["filter"] == other]
        assert later, f"half-done field {field_id} lost its {other} exposure"
        assert min(t(o["start"]).unix for o in later) - visits.earliest.unix >= CADENCE_S
    assert not [o for o in new["observations"] if o["field_id"] in pairs.one
                and o["filter"] == pairs.one[o["field_id"]].filters[0]]  # the filter done is not repeated
    assert [(r["revision"], r["final"]) for r in p.store.plans(SUPEREVENT)] == [(1, 1), (2, 1)]
    assert [(m["type"], m["plan_id"]) for m in p.sink.messages] == [("plan", new["plan_id"])]  # published
    assert [d["decision"] for d in p.store.decisions()] == ["plan", "replan"]


def test_a_slipped_plan_is_re_planned_from_now_once(loop):
    p, executed = loop
    first = the_plan(p)
    obs = first["observations"]
    write_executed(executed, executed_like(obs[:10]))
    now = after(obs[10]["start"], 900.0 + 120.0)  # the 11th observation is 17 min late: more than max_slip_s
    poll = poller(p).poll(now)
    assert [a.action for a in poll.replans] == ["replan"] and "slipped by 1020 s" in poll.replans[0].reason
    again = poller(p).poll(now)  # the re-plan job is open: nothing more
    assert [a.action for a in again.replans] == ["ignore"] and "is open" in again.replans[0].reason
    out = p.run_job(poll.replans[0].job)
    assert out.decision == "replan" and out.revision == 2
    new = the_plan(p)
    assert new["start"].startswith(now.isot[:19]) and min(t(o["start"]).unix for o in new["observations"]) >= now.unix
    assert poller(p).poll(now).replans == []  # the new revision is on time
    assert [j["status"] for j in replan_jobs(p.store, SUPEREVENT)] == ["done"]


def test_a_failed_exposure_re_plans_and_its_field_is_planned_again(loop):
    p, executed = loop
    obs = the_plan(p)["observations"]
    record = executed_like(obs[:9]) + executed_like(obs[9:10], fraction=0.0, status="failed")
    write_executed(executed, record)
    now = after(obs[9]["end"], 60.0)
    poll = poller(p).poll(now)
    assert [a.action for a in poll.replans] == ["replan"] and "1 exposure(s) failed" in poll.replans[0].reason
    out = p.run_job(poll.replans[0].job)
    assert out.decision == "replan"
    failed = (obs[9]["field_id"], obs[9]["filter"])
    assert failed in {(o["field_id"], o["filter"]) for o in the_plan(p)["observations"]}


def test_the_same_file_read_twice_changes_nothing(loop):
    p, executed = loop
    obs = the_plan(p)["observations"]
    write_executed(executed, executed_like(obs[:10]) + executed_like(obs[:3], fraction=0.4))  # lower reports too
    now = after(obs[9]["end"], 60.0)

    def table():
        c = sqlite3.connect(p.store.path)
        try:
            return c.execute("SELECT * FROM executed ORDER BY exposure_id").fetchall()
        finally:
            c.close()

    one = poller(p).poll(now)
    rows = table()
    two = poller(p).poll(now)
    assert (one.stored.added, one.stored.unchanged) == (10, 0)
    assert (two.stored.added, two.stored.updated, two.stored.unchanged) == (0, 0, 10)
    assert table() == rows and count_executed(p.store) == 10
    assert one.replans == two.replans == []


def test_a_malformed_record_gets_one_log_line_and_the_rest_is_stored(loop, caplog):
    p, executed = loop
    obs = the_plan(p)["observations"]
    write_executed(executed, executed_like(obs[:10]))
    lines = executed.read_text().splitlines()
    lines.insert(5, lines[5].replace('"processed_fraction": 1.0', '"processed_fraction": 1.7'))
    executed.write_text("\n".join(lines) + "\n")
    caplog.set_level(logging.WARNING)
    poll = poller(p).poll(after(obs[9]["end"], 60.0))
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1, [r.getMessage() for r in warnings]
    assert "line 6" in warnings[0].getMessage() and "processed_fraction 1.7" in warnings[0].getMessage()
    assert poll.stored.added == 10 and poll.error is None


def test_an_unreadable_source_is_one_line_and_nothing_changes(loop, caplog):
    p, executed = loop
    executed.write_bytes(b"\x89PNG\r\n\x1a\n not json lines at all")
    caplog.set_level(logging.WARNING)
    poll = poller(p).poll(after(the_plan(p)["observations"][9]["end"], 60.0))
    assert poll.error and poll.stored is None and count_executed(p.store) == 0
    assert len([r for r in caplog.records if r.levelno >= logging.WARNING]) == 1


def test_a_closure_of_an_event_without_a_plan_is_refused(loop):
    p, _ = loop
    acc = p.replan_closure("S990101zz", "2023-04-15T06:00:00Z", "test:closure")
    assert acc.action == "rejected" and "no current plan" in acc.reason
    bad = p.replan_closure(SUPEREVENT, "at dawn", "test:closure")
    assert bad.action == "rejected" and "ISO-8601" in bad.reason
