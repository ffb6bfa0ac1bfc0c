"""The following nights through the real pipeline (``executed.md`` L9-L11).

The loop's scenario (``loop_helpers``: MS181101ab's notice re-dated to
2023-04-15T02:55Z, planned by the real :class:`NoticePipeline` on real
SQLite with greedy) under ``[scheduler] nights = 2``: the alert's plan is
night 1's, the executed file holds its first exposures, and the poll's clock
(``now=``) is moved to night 2's evening twilight (``night_windows``).
"""

from __future__ import annotations

import dataclasses

import pytest
from astropy.time import Time, TimeDelta

from mushrooms.daemon.loop.poll import ExecutedLoop
from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.daemon.planning.nights import plans_as_done
from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.planning.replans import replan_jobs
from mushrooms.scheduler_core.executed import done_pairs
from mushrooms.scheduler_core.plan.schema import validate_document
from mushrooms.scheduler_core.sky.twilight import night_windows

from loop_helpers import (PLANNING, SENT, SUPEREVENT, copy_state, executed_like, loop_config, open_pipeline,
                          planned_state, t, the_plan, write_executed)

CADENCE_S = 1800.0
TWO = dataclasses.replace(PLANNING, nights=2)


def pipeline(state, loop: LoopConfig, planning=TWO) -> NoticePipeline:
    return open_pipeline(state, loop, planning)


@pytest.fixture(scope="module")
def planned_two(tmp_path_factory):
    """The notice planned with nights = 2 (revision 1: night 1's plan), once."""
    return planned_state(tmp_path_factory.mktemp("two"), TWO)


@pytest.fixture(scope="module")
def nights():
    return night_windows(Time(SENT.rstrip("Z"), scale="utc"), TWO, 2)


def at(time: Time, seconds: float) -> Time:
    return time + TimeDelta(seconds, format="sec")


def test_night_one_plan_ends_at_its_morning_twilight(planned_two, tmp_path, nights):
    p = pipeline(copy_state(planned_two, tmp_path), LoopConfig())
    try:
        doc = the_plan(p)
        assert t(doc["end"]).unix <= nights[0][1].unix + 1.0
        assert doc["observations"] and max(t(o["end"]).unix for o in doc["observations"]) <= nights[0][1].unix + 1
    finally:
        p.store.close()


def test_night_two_is_re_planned_once_at_its_start_without_a_done_pair(planned_two, tmp_path, nights):
    state = copy_state(planned_two, tmp_path)
    executed = tmp_path / "executed.jsonl"
    p = pipeline(state, loop_config(executed))
    first = the_plan(p)
    obs = first["observations"]
    ten = executed_like(obs[:10])
    write_executed(executed, ten)
    loop = ExecutedLoop(p.loop, p)
    night1 = loop.poll(at(t(obs[9]["end"]), 60.0))  # during night 1: read, on time, no re-plan
    assert (night1.read, night1.stored.added, night1.jobs) == (10, 10, [])
    between = loop.poll(at(nights[0][1], 3600.0))  # the day between the nights: nothing
    assert between.jobs == [] and replan_jobs(p.store, SUPEREVENT) == []
    evening = at(nights[1][0], 120.0)  # the first poll of night 2
    poll = loop.poll(evening)
    assert len(poll.jobs) == 1, poll.replans
    job = poll.jobs[0].job
    assert t(job.start).unix == pytest.approx(evening.unix, abs=1e-3)
    out = p.run_job(job)
    assert out.decision == "replan" and out.plan_id and out.supersedes == first["plan_id"], out
    new = the_plan(p)
    validate_document(new)
    assert (new["revision"], new["final"], new["supersedes"]) == (2, True, first["plan_id"])
    starts = [t(o["start"]).unix for o in new["observations"]]
    assert starts and min(starts) >= evening.unix - 1e-3  # inside night 2's window
    assert max(t(o["end"]).unix for o in new["observations"]) <= nights[1][1].unix + 1.0
    assert t(new["end"]).unix <= nights[1][1].unix + 1.0
    pairs = done_pairs(ten, ("g", "r"), cadence_s=CADENCE_S)
    assert pairs.both  # the executed file completes pairs on night 1
    assert not [o for o in new["observations"] if o["field_id"] in pairs.both]
    # the next poll of the night, and a restart on the same state file: night 2 is not re-planned again
    assert loop.poll(at(evening, 300.0)).jobs == []
    p.store.close()
    again = pipeline(state, loop_config(executed))
    try:
        assert ExecutedLoop(again.loop, again).poll(at(evening, 600.0)).jobs == []
        assert [r["revision"] for r in again.store.plans(SUPEREVENT)] == [1, 2]
        assert len(replan_jobs(again.store, SUPEREVENT)) == 1
        assert [d["decision"] for d in again.store.decisions()] == ["plan", "replan"]
    finally:
        again.store.close()


def test_night_two_waits_for_an_open_job_and_then_re_plans(planned_two, tmp_path, nights):
    """A job of the event open at the twilight: the night is not marked, the next poll re-plans it.

    The job is a closure of the day between the nights (it reopens before night 2: nothing of night 1 is
    left, so it ends without a plan and night 1's plan is still the current one at night 2's evening).
    """
    executed = tmp_path / "executed.jsonl"
    p = pipeline(copy_state(planned_two, tmp_path), loop_config(executed))
    try:
        write_executed(executed, [])
        evening = at(nights[1][0], 60.0)
        closure = p.replan_closure(SUPEREVENT, at(nights[1][0], -1800.0).isot + "Z", "test:closure",
                                   now=at(nights[0][1], 3600.0).to_datetime())
        assert closure.job is not None
        loop = ExecutedLoop(p.loop, p)
        assert loop.poll(evening).jobs == []  # the closure's job is open
        p.run_job(closure.job)
        later = loop.poll(at(evening, 300.0))
        assert len(later.jobs) == 1
    finally:
        p.store.close()


def test_with_one_night_the_next_evening_is_not_re_planned(planned_two, tmp_path, nights):
    """nights = 1 (the default): no night re-plan, whatever the clock says."""
    executed = tmp_path / "executed.jsonl"
    write_executed(executed, [])
    p = pipeline(copy_state(planned_two, tmp_path), loop_config(executed), planning=PLANNING)
    try:
        assert ExecutedLoop(p.loop, p).poll(at(nights[1][0], 120.0)).replans == []
        assert replan_jobs(p.store, SUPEREVENT) == []
    finally:
        p.store.close()


def test_without_a_source_night_two_counts_night_one_plan_as_done(planned_two, tmp_path, nights):
    """(L11) No executed source: night 2 is planned on night 1's plan taken as done."""
    from mushrooms.daemon.planning.nights import record_night_replans

    p = pipeline(copy_state(planned_two, tmp_path), LoopConfig())
    try:
        first = the_plan(p)
        evening = at(nights[1][0], 120.0)
        done = plans_as_done(p.store, SUPEREVENT, float(evening.unix))
        assert len(done) == len(first["observations"])
        acc = record_night_replans(p, evening)
        assert [a.action for a in acc] == ["replan"]
        assert record_night_replans(p, at(evening, 300.0)) == []  # once
        out = p.run_job(acc[0].job)
        assert out.decision == "replan" and out.plan_id, out
        new = the_plan(p)
        # what night 1 planned counts as held (N3): the executed pairs' coverage is night 1's plan's
        assert new["metrics"]["coverage_executed"] == pytest.approx(first["metrics"]["coverage"], abs=1e-6)
        pairs = done_pairs(done, ("g", "r"), cadence_s=CADENCE_S)
        assert pairs.both and not [o for o in new["observations"] if o["field_id"] in pairs.both]
        assert min(t(o["start"]).unix for o in new["observations"]) >= evening.unix - 1e-3
    finally:
        p.store.close()


def test_without_a_source_each_revision_counts_until_the_next_one_starts(planned_two, tmp_path, nights):
    """(L11, L14) A closure re-plan on night 1 with no source: revision 1 counts before the closing, 2 after."""
    p = pipeline(copy_state(planned_two, tmp_path), LoopConfig())
    try:
        first = the_plan(p)
        obs = first["observations"]
        closing = t(obs[9]["end"])
        reopening = at(closing, 7200.0)
        acc = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure", now=closing.to_datetime())
        out = p.run_job(acc.job)
        assert out.decision == "replan" and out.plan_id, out
        second = the_plan(p)
        before = [o for o in obs if t(o["start"]).unix < closing.unix]  # (L14) none while closed
        # night 1's re-plan took revision 1's exposures before the reopening as done: no done pair again
        pairs = done_pairs(executed_like(before), ("g", "r"), cadence_s=CADENCE_S)
        assert pairs.both and not [o for o in second["observations"] if o["field_id"] in pairs.both]
        assert t(second["end"]).unix <= nights[0][1].unix + 1.0  # the rest of night 1 (L10)
        done = plans_as_done(p.store, SUPEREVENT, float(at(nights[1][0], 120.0).unix))
        key = lambda o: (int(o["field_id"]), o["filter"], round(t(o["start"]).unix, 3))  # noqa: E731
        assert sorted((e.field_id, e.filter, round(float(e.start.unix), 3)) for e in done) == sorted(
            key(o) for o in before + second["observations"])
    finally:
        p.store.close()


def test_with_revisit_night_two_observes_night_one_fields_again(planned_two, tmp_path, nights):
    """(N4) revisit = true: night 2 is planned on the whole map again, night 1's fields re-observed."""
    from mushrooms.daemon.planning.nights import record_night_replans

    # the state was planned with revisit = false; the re-plan reads [scheduler] as configured now
    p = pipeline(copy_state(planned_two, tmp_path), LoopConfig(), planning=dataclasses.replace(TWO, revisit=True))
    try:
        first = the_plan(p)
        evening = at(nights[1][0], 120.0)
        (acc,) = record_night_replans(p, evening)
        out = p.run_job(acc.job)
        assert out.decision == "replan" and out.plan_id, out
        new = the_plan(p)
        assert not new["metrics"]["coverage_executed"]  # nothing of night 1 counted as done
        assert {o["field_id"] for o in new["observations"]} & {o["field_id"] for o in first["observations"]}
        assert min(t(o["start"]).unix for o in new["observations"]) >= evening.unix - 1e-3
        validate_document(new)
    finally:
        p.store.close()
