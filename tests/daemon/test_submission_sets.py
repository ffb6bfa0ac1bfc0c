"""The submitter's lifecycle under faults: queue sets, stuck events, kicks, retractions in flight, gates.

Real plans from the notice pipeline, a real store, Kowalski's contract
server on loopback (``contract_servers.py``).  A revision goes to Kowalski
as the ordered list of queues of
:func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queues`; the set
used here splits a plan's targets in three so that every property holds
for K > 1.
"""

from __future__ import annotations

import dataclasses
import json
import threading
import time

import pytest

from mushrooms.daemon.drain import OutboxDrain
from mushrooms.daemon.submission.submitter import gate, submissions
from mushrooms.scheduler_core.plan import exports
from mushrooms.scheduler_core.plan.exports import ExportConfig
from test_submissions import SID, TOKEN, World, _config, Killed, kowalski, server, world  # noqa: F401 (fixtures)

K = 3


def three_queues(plan, export=ExportConfig(), name_base=None):
    """A plan's targets dealt into three queues named ``<name_base>_1..3`` (a queue set with K = 3)."""
    one = exports.to_trigger_queue(plan, export, queue_name=name_base)
    targets = one["targets"]
    return [{**one, "queue_name": f"{name_base}_{k + 1}", "targets": targets[k::K]} for k in range(K)]


@pytest.fixture
def sets(monkeypatch):
    monkeypatch.setattr(exports, "to_trigger_queues", three_queues)


def names(world: World, revision: int) -> list[str]:
    """The K queues of the event's ``revision``-th submitted set (named by the one rule from the plan's id)."""
    (row,) = [s for s in submissions(world.store) if s.revision == revision]
    return [f"{row.queue_name}_{k}" for k in range(1, K + 1)]


def test_a_revision_puts_its_whole_set_before_deleting_the_old_set_and_a_retraction_deletes_all(
        sets, world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    assert world.submitter.step() == 0
    assert sorted(kowalski.queues) == names(world, 1)
    world.notice("MS230425l-preliminary.json", SID)
    assert world.submitter.step() == 0
    assert kowalski.lines()[K:] == ([f"PUT /api/triggers/ztf {n} -> 200" for n in names(world, 2)]
                                    + [f"DELETE /api/triggers/ztf {n} -> 200" for n in names(world, 1)])
    assert sorted(kowalski.queues) == names(world, 2)
    world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    assert world.submitter.step() == 0
    assert kowalski.queues == {}
    assert [s.state for s in submissions(world.store)] == ["replaced", "deleted"]
    assert world.submitter.step() == 0 and len(kowalski.log) == 4 * K


def test_a_kill_between_two_puts_of_a_set_leaves_no_queue_twice_and_none_orphaned(sets, world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    real, calls = world.submitter.client.put, []

    def put_then_die_on_the_second(queue):
        calls.append(queue["queue_name"])
        answer = real(queue)
        if len(calls) == 2:
            raise Killed("put")
        return answer

    world.submitter.client.put = put_then_die_on_the_second
    with pytest.raises(Killed):
        world.submitter.step()
    world.restart()
    assert world.submitter.step() == 0
    assert sorted(kowalski.queues) == names(world, 1)
    puts = [e["queue_name"] for e in kowalski.log if e["method"] == "PUT" and e["status"] == 200]
    assert sorted(puts) == names(world, 1)  # each accepted once; the repeat was a 409 with the same content
    (row,) = submissions(world.store)
    assert row.state == "submitted"


def test_one_stuck_event_does_not_hold_the_other_events_queues(tmp_path, kowalski) -> None:
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, timeout_s=0.5))
    try:
        kowalski.hang_s = 4.0
        for sid in ("S1", "S2", "S3"):
            w.notice("MS181101ab-preliminary.json", sid)
        kowalski.faults["PUT"] = ["drip"]  # the first PUT (S1's) is answered one byte every 0.1 s
        assert w.submitter.step() == 1
        rows = {s.superevent_id: s for s in submissions(w.store)}
        assert rows["S2"].state == rows["S3"].state == "submitted"
        assert {n.split("_")[2] for n in kowalski.queues} == {"S2", "S3"}
        assert rows["S1"].state == "pending" and "deadline" in rows["S1"].answer
    finally:
        kowalski.release.set()
        w.store.close()


def test_a_kick_now_during_a_failing_pass_runs_the_next_pass_at_once() -> None:
    entered, go, passes = threading.Event(), threading.Event(), []

    def flush() -> int:
        passes.append(time.monotonic())
        if len(passes) == 1:
            entered.set()
            go.wait(10)
            raise ConnectionError("the server failed this pass")
        return 0

    drain = OutboxDrain(flush, initial_s=300.0, max_s=300.0, name="submit")
    try:
        drain.kick()
        assert entered.wait(10)
        drain.kick(now=True)  # a retraction arrives while the pass is failing
        go.set()
        for _ in range(100):
            if len(passes) >= 2:
                break
            time.sleep(0.05)
        assert len(passes) == 2, "the kick was swallowed by the failed pass's back-off"
    finally:
        drain.close()


def test_a_retraction_during_an_in_flight_put_deletes_the_older_revision(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    world.notice("MS230425l-preliminary.json", SID)
    kowalski.block_after.add("PUT")
    t = threading.Thread(target=world.submitter.step)
    t.start()
    try:
        assert kowalski.blocked.wait(10)
        world.notice("MS181101ab-retraction.json", time_created="2023-04-26T00:00:00Z")
    finally:
        kowalski.release.set()
        t.join(20)
    world.submitter.step()
    assert kowalski.queues == {}
    assert [s.state for s in submissions(world.store)] == ["deleted", "deleted"]
    assert [d["state"] for d in world.documents()] == ["submitted", "submitted", "deleted", "deleted"]


def test_an_interrupted_older_revision_is_settled_when_the_newest_plan_is_gated_out(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    world.notice("MS230425l-preliminary.json", SID)
    kowalski.faults["PUT"] = [500]
    assert world.submitter.step() == 1  # r2 attempted once, waits for a retry
    world.submitter.submit = dataclasses.replace(world.submitter.submit, min_coverage=0.9999)
    world.notice("MS181101ab-ext-update.json", SID, time_created="2024-01-01T00:00:00Z")  # gated out
    assert world.submitter.step() == 0
    # r2's PUT had no usable answer (a 5xx: maybe applied): it is watched for until its queue's window ends
    # (issue 52, finding 1), not a submission waiting
    assert world.submitter.watching == 1 and "watching for" in submissions(world.store)[1].reason
    with world.store.transaction() as c:  # the night passed: r2's queues' windows ended
        (plan_id, body), = c.execute("SELECT plan_id, body FROM submissions WHERE revision=2").fetchall()
        queues = [{**q, "validity_window_mjd": [50000.0, 50000.5]} for q in json.loads(body)]
        c.execute("UPDATE submissions SET body=? WHERE plan_id=?", (json.dumps(queues), plan_id))
    assert world.submitter.step() == 0
    states = [(s.revision, s.state) for s in submissions(world.store)]
    assert states[0] == (1, "submitted") and states[1][1] not in ("pending", "submitted") and states[2][1] == "skipped"
    assert world.submitter.step() == 0 and world.submitter.watching == 0


def test_a_submitted_queue_whose_window_ended_is_no_longer_an_open_row(world, kowalski) -> None:
    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    with world.store.transaction() as c:  # the night passed: the plan's validity window ended
        (plan_id, doc), = c.execute("SELECT plan_id, document FROM plans").fetchall()
        d = json.loads(doc)
        d["end"] = "2001-01-01T00:00:00Z"
        c.execute("UPDATE plans SET document=? WHERE plan_id=?", (json.dumps(d), plan_id))
    world.submitter.step()
    (row,) = submissions(world.store)
    assert row.state == "submitted" and row.finished_at is not None
    assert world.submitter.open_events() == []


def test_a_replan_is_gated_on_the_total_coverage_it_leads_to(world) -> None:
    world.notice("MS181101ab-preliminary.json")
    doc = world.store.plans()[-1]["document"]
    sub = dataclasses.replace(world.submitter.submit, min_coverage=0.3)
    replan = {**doc, "metrics": {**doc["metrics"], "coverage": 0.05, "coverage_executed": 0.40}}
    assert gate(replan, sub, now=0.0) is None  # 0.45 in all: the executed pairs count
    lone = {**doc, "metrics": {**doc["metrics"], "coverage": 0.05}}
    lone["metrics"].pop("coverage_executed", None)
    assert "below [submit] min_coverage" in gate(lone, sub, now=0.0)


def test_queue_list_groups_the_queues_by_event_and_revision_with_utc_windows(sets, world, kowalski, capsys,
                                                                             monkeypatch) -> None:
    from mushrooms.cli import main

    world.notice("MS181101ab-preliminary.json")
    world.submitter.step()
    kowalski.queues["ToO_manual"] = {"queue_name": "ToO_manual", "validity_window_mjd": [60000.123456789012, 60001.0],
                                     "targets": [{"field_id": 1, "filter_id": 1, "exposure_time": 30}]}
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", TOKEN)
    capsys.readouterr()
    assert main(["queue", "list", "--url", kowalski.url]) == 0
    out = capsys.readouterr().out
    (row,) = submissions(world.store)
    assert f"{SID} plan {row.plan_id.removeprefix('mushrooms-')[:12]}: {K} queue(s)" in out
    assert "2023-02-25T02:57" in out and "60000.123456789012" not in out
    for n in names(world, 1):
        assert n in out
    assert "ToO_manual" in out and "targets" in out
