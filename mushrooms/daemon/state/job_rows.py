"""The ``jobs`` table's side of the state file: starting, parking, finishing and failing planning jobs.

A part of :class:`~mushrooms.daemon.state.store.Store` (a mixin it is built
from): every method runs on the store's connections and inside its
transactions, so that a job's status, its plans and its outbox rows change
together.  The job states are :class:`~mushrooms.daemon.state.records.JobState`.
"""

from __future__ import annotations

import json
import sqlite3
from typing import Any

from ...handlers.instants import now_iso_z
from ...handlers.text import storable
from ...scheduler_core.plan import strict_json
from ...scheduler_core.plan.messages import plan_final_message
from . import current_event
from .records import OPEN_JOBS, Job, JobState, job_from_row, now_iso

__all__ = ["JobRows", "FALLBACK_ATTEMPTS"]

#: Starts of a job that died with the fast scheduler after the optimiser's ``max_attempts``.
FALLBACK_ATTEMPTS = 2


class JobRows:
    """The planning jobs' rows: what :class:`~mushrooms.daemon.state.store.Store` does with a job.

    It keeps which jobs this process started (``running``) and which it
    parked (first plan stored, waiting for an optimisation slot), so that a
    clean stop gives their starts back (:meth:`release_unfinished`).  It
    uses the store's ``connection()``, ``transaction()`` and
    ``insert_outbox()``.
    """

    def init_job_rows(self) -> None:
        """No job started or parked by this process yet (called by the store's ``__init__``)."""
        self._started: set[int] = set()  # jobs this process started and has not finished
        self._parked: set[int] = set()  # first plan stored, waiting for an optimisation slot (start given back)

    def pending_jobs(self) -> list[Job]:
        """Jobs accepted but not finished (``pending``, or ``running`` when a crash interrupted them), oldest first.

        Read-only.  At start the daemon runs these again (the newest per
        superevent is enough: older ones are already ``superseded``).  A job
        started too often (it crashed the process each time) is refused by
        :meth:`start_job`.
        """
        rows = self.connection().execute(
            "SELECT * FROM jobs WHERE status IN ('pending','running') ORDER BY job_id").fetchall()
        return [job_from_row(r) for r in rows]

    def job(self, job_id: int) -> Job | None:
        """One job by id."""
        row = self.connection().execute("SELECT * FROM jobs WHERE job_id=?", (job_id,)).fetchone()
        return None if row is None else job_from_row(row)

    def start_job(self, job_id: int, max_attempts: int = 3) -> Job | None:
        """Mark a job running (attempts + 1) and fix what it supersedes.

        Degrade, never drop: a job whose starts died ``max_attempts`` times
        (it crashed the process each time) comes back with ``fallback`` set,
        to be planned by the fast scheduler alone, for up to
        :data:`FALLBACK_ATTEMPTS` more starts.  Only then is it marked
        ``failed``; its event then has no plan, so the next notice for it is
        planned again (see :func:`~mushrooms.handlers.decisions.decide`).

        Returns None when the job is no longer runnable: superseded, cancelled
        by a retraction, finished, or given up.  :meth:`job_status` tells which.
        """
        with self.transaction() as c:
            row = c.execute("SELECT * FROM jobs WHERE job_id=?", (job_id,)).fetchone()
            if row is None or row["status"] not in OPEN_JOBS:
                return None
            if row["attempts"] >= max_attempts + FALLBACK_ATTEMPTS:
                why = (f"gave up after {row['attempts']} unfinished attempts (the last "
                       f"{FALLBACK_ATTEMPTS} with the fast scheduler)")
                first = c.execute("SELECT plan_id FROM plans WHERE job_id=? AND withdrawn=0 ORDER BY seq DESC"
                                  " LIMIT 1", (job_id,)).fetchone()
                if first is not None:  # a revision went out: it stands, and the contract's plan_final says so
                    self._close_with(c, job_id, first[0], row["superevent_id"], why)
                    return None
                c.execute("UPDATE jobs SET status='failed', reason=?, finished_at=? WHERE job_id=?",
                          (why, now_iso(), job_id))
                return None
            fallback = row["attempts"] >= max_attempts
            prev = c.execute("SELECT plan_id FROM plans WHERE superevent_id=? AND withdrawn=0"
                             " AND job_id IS NOT ? ORDER BY seq DESC LIMIT 1",
                             (row["superevent_id"], job_id)).fetchone()
            supersedes = prev[0] if prev else None
            c.execute("UPDATE jobs SET status='running', attempts=attempts+1, supersedes=? WHERE job_id=?",
                      (supersedes, job_id))
            row = c.execute("SELECT * FROM jobs WHERE job_id=?", (job_id,)).fetchone()
            self._started.add(job_id)
        return job_from_row(row, fallback=fallback)

    def park_job(self, job_id: int) -> None:
        """The job's first plan is stored and it now only waits for an optimisation slot: give its start back.

        A process killed while the job waits did not die of this job, so the
        wait never counts towards :meth:`start_job`'s fallback;
        :meth:`resume_job` counts the start again when the optimisation
        begins.
        """
        with self.transaction() as c:
            if c.execute("UPDATE jobs SET attempts=MAX(attempts-1, 0) WHERE job_id=? AND status='running'",
                         (job_id,)).rowcount:
                self._started.discard(job_id)
                self._parked.add(job_id)

    def resume_job(self, job_id: int) -> bool:
        """A parked job's optimisation begins: count the start (False when the job is no longer running)."""
        with self.transaction() as c:
            ok = bool(c.execute("UPDATE jobs SET attempts=attempts+1 WHERE job_id=? AND status='running'",
                                (job_id,)).rowcount)
            self._parked.discard(job_id)
            if ok:
                self._started.add(job_id)
            return ok

    def release_unfinished(self) -> list[int]:
        """At a clean stop: give back the starts of jobs this process left running.

        They become ``pending`` with the start not counted (only starts that
        died count towards giving up) and run again at the next start.
        Parked jobs (start already given back) just become ``pending``.
        Returns their ids.
        """
        with self.transaction() as c:
            released = [j for j in sorted(self._started) if c.execute(
                "UPDATE jobs SET status='pending', attempts=MAX(attempts-1, 0) WHERE job_id=? AND status='running'",
                (j,)).rowcount]
            released += [j for j in sorted(self._parked) if c.execute(
                "UPDATE jobs SET status='pending' WHERE job_id=? AND status='running'", (j,)).rowcount]
            self._started.clear()
            self._parked.clear()
        return sorted(released)

    def plan_epoch(self, job_id: int) -> int:
        """Withdrawals of the job's superevent decided before the job's notice (0: never withdrawn).

        Fixed once the job is accepted, so a job re-run after a crash gets
        the same plan ids; the pipeline salts the plan id with it.
        """
        row = self.connection().execute(
            "SELECT COUNT(*) FROM decisions d JOIN jobs j ON d.superevent_id=j.superevent_id"
            " WHERE j.job_id=? AND d.decision='withdraw' AND d.notice_id<j.notice_id", (job_id,)).fetchone()
        return int(row[0]) if row else 0

    def job_status(self, job_id: int) -> str | None:
        """``pending``, ``running``, ``done``, ``failed``, ``superseded``, ``cancelled`` (None: no such job)."""
        row = self.connection().execute("SELECT status FROM jobs WHERE job_id=?", (job_id,)).fetchone()
        return None if row is None else str(row[0])

    def describe_job(self, job_id: int) -> str:
        """Status with its reason, e.g. ``superseded (newer sky map)``, for log lines."""
        row = self.connection().execute("SELECT status, reason FROM jobs WHERE job_id=?", (job_id,)).fetchone()
        if row is None:
            return "unknown job"
        return str(row[0]) + (f" ({row[1]})" if row[1] and row[0] in (JobState.FAILED, JobState.SUPERSEDED, JobState.CANCELLED) else "")

    def latest_planned_notice(self, superevent_id: str) -> tuple[int, bytes] | None:
        """The notice of the event's current map, with its raw bytes (:func:`~mushrooms.daemon.state.current_event.planned_notice`)."""
        return current_event.planned_notice(self.connection(), superevent_id)

    def first_start(self, *superevent_ids: str) -> str | None:
        """The earliest horizon start (ISO-8601 UTC) of the jobs of these superevents, or None if they have none.

        An event's follow-up begins there (:func:`~mushrooms.daemon.state.current_event.first_start`, C4): the loop reads
        executed exposures from it, and its night re-plans count nights from it.
        """
        return current_event.first_start(self.connection(), *superevent_ids)

    def asked_at(self, job_id: int) -> float | None:
        """Unix time the job was asked for (:func:`~mushrooms.daemon.state.current_event.asked_at`), or None."""
        return current_event.asked_at(self.connection(), job_id)

    def notice_raw(self, notice_id: int) -> bytes | None:
        """Raw bytes of a stored notice (kept for notices that need planning)."""
        row = self.connection().execute("SELECT raw FROM notices WHERE notice_id=?", (notice_id,)).fetchone()
        return None if row is None or row[0] is None else bytes(row[0])

    def finish_job(self, job_id: int, plan_id: str, document: dict[str, Any],
                   coverage: float, latency_s: float) -> int | None:
        """Store the plan, close the job and queue the plan message, atomically.

        Returns the outbox id, or None when the job was superseded or
        cancelled while it ran (the plan is then dropped).  Same as
        :meth:`store_revision` with ``final=True``.
        """
        return self.store_revision(job_id, plan_id, document, coverage, latency_s, final=True)

    def store_revision(self, job_id: int, plan_id: str, document: dict[str, Any], coverage: float,
                       latency_s: float, final: bool, revision: int | None = None) -> int | None:
        """Store one revision of a running job's plan and queue its message, atomically.

        A job publishes its fast plan as revision 1 and possibly a better
        one as revision 2; the final revision also closes the job
        (``done``).  Idempotent across a crash and restart: a revision this
        job already stored (same ``plan_id``) is not queued again.

        Parameters
        ----------
        job_id : int
        plan_id : str
        document : dict
            The plan document (with its ``revision`` and ``final``).
        coverage, latency_s : float
        final : bool
            No further revision follows: close the job.
        revision : int, optional
            Default ``document["revision"]``, else 1.

        Returns
        -------
        int or None
            The outbox id (the earlier one when already stored), or None when
            the job was superseded or cancelled meanwhile (nothing stored).
        """
        revision = int(revision if revision is not None else document.get("revision", 1))
        with self.transaction() as c:
            row = c.execute("SELECT status, superevent_id FROM jobs WHERE job_id=?", (job_id,)).fetchone()
            if row is None or row["status"] != JobState.RUNNING:
                return None
            now = now_iso()
            mine = c.execute("SELECT 1 FROM plans WHERE plan_id=? AND job_id=?", (plan_id, job_id)).fetchone()
            outbox_id = None
            if mine is not None:
                found = c.execute("SELECT outbox_id FROM outbox WHERE key=? AND kind='plan' ORDER BY outbox_id DESC"
                                  " LIMIT 1", (plan_id,)).fetchone()
                outbox_id = None if found is None else int(found[0])
            if outbox_id is None:
                seq = c.execute("SELECT COALESCE(MAX(seq), 0) + 1 FROM plans").fetchone()[0]
                c.execute("INSERT INTO plans(plan_id, superevent_id, job_id, created_at, seq, withdrawn, document,"
                          " revision, final) VALUES (?,?,?,?,?,0,?,?,?) ON CONFLICT(plan_id) DO UPDATE SET"
                          " withdrawn=0, job_id=excluded.job_id, seq=excluded.seq, document=excluded.document,"
                          " revision=excluded.revision, final=excluded.final",
                          (plan_id, row["superevent_id"], job_id, now, seq, strict_json.dumps(document), revision,
                           int(final)))
                outbox_id = self.insert_outbox(c, plan_id, "plan", document)
            if final:
                c.execute("UPDATE jobs SET status='done', plan_id=?, coverage=?, latency_s=?, reason=NULL,"
                          " finished_at=? WHERE job_id=?", (plan_id, coverage, latency_s, now, job_id))
                self._started.discard(job_id)
                self._parked.discard(job_id)
            else:
                c.execute("UPDATE jobs SET plan_id=?, coverage=?, latency_s=? WHERE job_id=?",
                          (plan_id, coverage, latency_s, job_id))
            return outbox_id

    def close_job(self, job_id: int, plan_id: str, reason: str) -> int | None:
        """Close a running job on its stored revision ``plan_id`` and queue the ``plan_final`` message.

        Returns the outbox id (the earlier one after a restart), or None when
        the job is no longer running (superseded, cancelled: nothing queued).
        """
        with self.transaction() as c:
            row = c.execute("SELECT status, superevent_id FROM jobs WHERE job_id=?", (job_id,)).fetchone()
            if row is None or row["status"] != JobState.RUNNING:
                return None
            return self._close_with(c, job_id, plan_id, row["superevent_id"], reason)

    def _close_with(self, c: sqlite3.Connection, job_id: int, plan_id: str, superevent_id: str, reason: str) -> int:
        """Mark the job done on ``plan_id`` (its revisions final) and queue ``plan_final`` once (lock held)."""
        c.execute("UPDATE plans SET final=1 WHERE job_id=?", (job_id,))
        c.execute("UPDATE jobs SET status='done', plan_id=?, reason=?, finished_at=? WHERE job_id=?",
                  (plan_id, reason[:500], now_iso(), job_id))
        self._started.discard(job_id)
        self._parked.discard(job_id)
        key = f"{plan_id}-final"
        found = c.execute("SELECT outbox_id FROM outbox WHERE key=? ORDER BY outbox_id DESC LIMIT 1",
                          (key,)).fetchone()
        if found is not None:
            return int(found[0])
        return self.insert_outbox(c, key, "plan_final", plan_final_message(plan_id, superevent_id, reason, now_iso_z()))

    def close_without_plan(self, job_id: int, reason: str) -> bool:
        """Close a running job that stores no plan (a re-plan with nothing left): ``done``; False if not running."""
        with self.transaction() as c:
            done = c.execute("UPDATE jobs SET status='done', reason=?, finished_at=? WHERE job_id=?"
                             " AND status='running'", (reason[:500], now_iso(), job_id)).rowcount
            self._started.discard(job_id)
            self._parked.discard(job_id)
        return bool(done)

    def job_plans(self, job_id: int) -> list[dict[str, Any]]:
        """The revisions a job stored, oldest first (documents parsed)."""
        rows = self.connection().execute(
            "SELECT plan_id, revision, final, withdrawn, document FROM plans WHERE job_id=? ORDER BY seq",
            (job_id,)).fetchall()
        return [dict(r) | {"document": json.loads(r["document"])} for r in rows]

    def fail_job(self, job_id: int, reason: str, retry_same_map: bool = False) -> None:
        """Close a job that cannot produce a plan (bad sky map, checker, bug).

        With ``retry_same_map`` (a failure on our side, not a bad map), the
        superevent forgets the job's sky map, so the next notice carrying the
        same map is planned again instead of being a ``duplicate``.
        """
        with self.transaction() as c:
            row = c.execute("SELECT superevent_id, skymap_sha256 FROM jobs WHERE job_id=?", (job_id,)).fetchone()
            c.execute("UPDATE jobs SET status='failed', reason=?, finished_at=? WHERE job_id=?"
                      " AND status IN ('pending','running')", (storable(reason, 2000), now_iso(), job_id))
            self._started.discard(job_id)
            self._parked.discard(job_id)
            if retry_same_map and row is not None:
                c.execute("UPDATE events SET skymap_sha256=NULL, updated_at=? WHERE superevent_id=?"
                          " AND skymap_sha256=?", (now_iso(), row[0], row[1]))
