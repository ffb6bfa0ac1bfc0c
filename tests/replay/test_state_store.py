"""The SQLite store: schema, durability across reopen, jobs lifecycle, threads."""

from __future__ import annotations

import sqlite3
import threading

import pytest

from mushrooms.daemon.state.store import SCHEMA_VERSION, NoticeRecord, Store, StoreError
from mushrooms.handlers.decisions import Decision


def rec(i: int, sid: str = "S1", raw: bytes | None = b"x") -> NoticeRecord:
    return NoticeRecord(origin=f"test:{i}", sha256=f"{i:064x}", size=1, received_at="2024-01-01T00:00:00Z",
                        superevent_id=sid, alert_type="PRELIMINARY", time_created="2024-01-01T00:00:00Z", raw=raw)


def plan(store: Store, i: int, sid: str = "S1", sha: str = "a"):
    return store.record_decision(rec(i, sid), lambda led: Decision("plan", sid, "new", "PRELIMINARY", sha),
                                 lambda d: "2024-01-01T00:00:00.000Z", received_wall=0.0)


def test_schema_wal_and_reopen(tmp_path):
    path = tmp_path / "state.sqlite"
    s = Store(path)
    nid, d, job, cancelled, _ = plan(s, 1)
    assert d.action == "plan" and job.status == "pending" and cancelled == []
    s.close()
    c = sqlite3.connect(path)
    assert c.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    assert c.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    c.close()
    s2 = Store(path)  # a restart finds the accepted job
    jobs = s2.pending_jobs()
    assert [j.job_id for j in jobs] == [job.job_id]
    assert s2.notice_raw(nid) == b"x"
    assert s2.event_state("S1").skymap_sha256 == "a"
    s2.close()


def test_newer_schema_and_non_database_are_refused(tmp_path):
    p = tmp_path / "new.sqlite"
    c = sqlite3.connect(p)
    c.execute("PRAGMA user_version=99")
    c.close()
    with pytest.raises(StoreError, match="newer"):
        Store(p)
    bad = tmp_path / "bad.sqlite"
    bad.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(StoreError, match="not a usable SQLite database"):
        Store(bad)


def test_failed_decision_transaction_leaves_nothing(tmp_path):
    s = Store(tmp_path / "s.sqlite")

    def boom(ledger):
        raise RuntimeError("crash inside the transaction")

    with pytest.raises(RuntimeError):
        s.record_decision(rec(1), boom, lambda d: "t", received_wall=0.0)
    assert s.counts()["notices"] == 0 and s.counts()["decisions"] == 0


def test_rerun_supersedes_open_job_and_crashed_job_is_given_up(tmp_path):
    s = Store(tmp_path / "s.sqlite")
    _, _, j1, _, _ = plan(s, 1, sha="a")
    _, _, j2, cancelled, _ = plan(s, 2, sha="b")
    assert cancelled == [j1.job_id]
    assert s.job_status(j1.job_id) == "superseded"
    assert s.start_job(j1.job_id) is None
    for _ in range(3):  # started three times, never finished: it crashed the process each time
        assert not s.start_job(j2.job_id).fallback
    assert [j.job_id for j in s.pending_jobs()] == [j2.job_id]
    for _ in range(2):  # degrade, never drop: two more starts with the fast scheduler only
        assert s.start_job(j2.job_id, max_attempts=3).fallback
    assert s.start_job(j2.job_id, max_attempts=3) is None
    assert s.job_status(j2.job_id) == "failed"
    assert s.describe_job(j2.job_id).startswith("failed (gave up after 5")
    assert s.pending_jobs() == []


def test_finish_job_after_cancellation_drops_the_plan(tmp_path):
    s = Store(tmp_path / "s.sqlite")
    _, _, job, _, _ = plan(s, 1)
    s.start_job(job.job_id)
    s.record_decision(rec(2, raw=None), lambda led: Decision("withdraw", "S1", "retracted", "RETRACTION"),
                      lambda d: None, received_wall=0.0,
                      withdrawal=lambda d, nid: {"type": "withdrawal", "withdrawal_id": "w1",
                                                 "superevent_id": "S1", "plan_ids": [], "reason": "r",
                                                 "created": "now"})
    assert s.finish_job(job.job_id, "p1", {"type": "plan", "plan_id": "p1"}, 0.5, 1.0) is None
    assert s.plans() == []
    assert [m.key for m in s.pending_outbox()] == ["w1"]
    assert s.event_state("S1").retracted


def test_plan_outbox_and_event_state(tmp_path):
    s = Store(tmp_path / "s.sqlite")
    _, _, job, _, _ = plan(s, 1)
    started = s.start_job(job.job_id)
    assert started.status == "running" and started.attempts == 1 and started.supersedes is None
    oid = s.finish_job(job.job_id, "p1", {"type": "plan", "plan_id": "p1"}, 0.5, 1.0)
    assert [m.outbox_id for m in s.pending_outbox()] == [oid]
    s.mark_published(oid)
    assert s.pending_outbox() == []
    assert s.event_state("S1").plan_ids == ("p1",)
    _, _, job2, _, _ = plan(s, 2, sha="b")
    assert s.start_job(job2.job_id).supersedes == "p1"


def test_two_threads_write_concurrently(tmp_path):
    s = Store(tmp_path / "s.sqlite")
    errors = []

    def worker(k):
        try:
            for i in range(40):
                plan(s, k * 1000 + i, sid=f"S{k}x{i}")
        except Exception as exc:  # pragma: no cover - the assertion below reports it
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert s.counts()["jobs"] == 80 and len(s.pending_jobs()) == 80
    s.close()
