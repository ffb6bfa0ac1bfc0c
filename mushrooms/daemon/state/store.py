"""The service's durable state: one SQLite file (WAL), schema-versioned.

Tables
------
``notices``   every message received: sha256, size, origin, when; the raw bytes
              for notices that need planning (a job re-reads its sky map from
              them after a crash); of a rejected one only the first KiB, and
              only for a retention period (:meth:`Store.prune_raw`).
``decisions`` one row per notice: what was decided and why (``plan``,
              ``rerun``, ``duplicate``, ``withdraw``, ``ignore``, ``rejected``).
``events``    per superevent: last sky map accepted for planning, retracted flag,
              ``time_created`` of the newest notice accepted (creation order).
``jobs``      planning jobs: ``pending`` -> ``running`` -> ``done`` | ``failed``
              | ``superseded`` | ``cancelled``, with the horizon start fixed at
              accept time (so a re-run gives the same plan id).
``plans``     plan documents (JSON) and whether they were withdrawn; a job's
              revisions (1: the fast plan, 2: a better optimised one) and
              whether the revision is ``final``.
``submissions`` plans submitted to ZTF's queue: ``pending`` -> ``submitted``
              -> ``replaced`` | ``deleted``, or ``rejected`` | ``failed`` |
              ``skipped``, with the queue name, body, remote answer and times
              (:mod:`~mushrooms.daemon.submission.submitter` reads and writes it).
``outbox``    messages to publish; ``published_at`` is set once the sink took
              them.  Publication is at-least-once: a crash between publishing
              and marking re-publishes the same message (same key).
``incidents`` what an operator must hear of besides notices (the consumer's
              offset jumps); created when missing at every open.
``executed``  exposures the telescope took, as ``[loop] executed_source``
              reported them: one row per exposure (:mod:`~mushrooms.daemon.state.executed`).

Crash safety: every state change that belongs together happens in one
``BEGIN IMMEDIATE`` transaction (accept = notice + decision + event + job or
withdrawal outbox row; finishing a job = plan + job status + outbox row).

Integrity: an existing file must be a SQLite database that passes
``PRAGMA quick_check`` (an empty or damaged file is refused with one line,
never silently replaced); a new file is created 0600 (0640 when group
readable).  One daemon per state file: :func:`lock_state` holds an exclusive
``flock`` on the database file itself (SQLite's own locks are POSIX record
locks, which ``flock`` does not touch).

Threads: each thread gets its own connection; write transactions are also
serialised by a process-wide lock, so the consumer thread and job threads can
share one :class:`Store`.

How the daemon uses it (see :class:`~mushrooms.daemon.intake.pipeline.NoticePipeline`):
``pipeline.accept`` records the decision durably, then the daemon commits the
Kafka offset; at start it runs :meth:`Store.pending_jobs` again (accepted but
not finished) and calls :meth:`~mushrooms.daemon.intake.pipeline.NoticePipeline.flush_outbox`.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sqlite3
import threading
import time
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterator

from ...handlers.decisions import Decision, EventState, newest_created
from ...handlers.instants import now_iso_z
from ...handlers.text import storable
from ...scheduler_core.plan import strict_json
from ...scheduler_core.plan.messages import plan_final_message
from . import current_event
from .file import StateInUse, StateLock, StoreError, create_or_check_file, lock_state
from .records import Job, NoticeRecord, OutboxMessage, job_from_row, now_iso, without_raw
from .schema import SCHEMA, SCHEMA_VERSION, missing_steps

__all__ = ["Store", "StoreError", "StateInUse", "StateLock", "lock_state", "Job", "OutboxMessage", "NoticeRecord",
           "SCHEMA_VERSION", "RAW_PREFIX_BYTES", "plan_final_message"]

log = logging.getLogger("mushrooms.daemon.store")

_OPEN = ("pending", "running")

#: Bytes kept of a rejected message (with its SHA-256 and size): enough to see what it was.
RAW_PREFIX_BYTES = 1024

#: Starts of a job that died with the fast scheduler after the optimiser's ``max_attempts``.
FALLBACK_ATTEMPTS = 2


class _TxLedger:
    """Ledger view over one open transaction."""

    def __init__(self, conn: sqlite3.Connection):
        self.conn = conn

    def event_state(self, superevent_id: str) -> EventState | None:
        return current_event.event_state(self.conn, superevent_id)


class Store:
    """SQLite state of the service; implements the handlers' ``Ledger``.

    Parameters
    ----------
    path : str or Path
        The database file.  A new one is created 0600 (SQLite gives its
        ``-wal`` and ``-shm`` files the same mode); an existing one must be
        a database that passes ``PRAGMA quick_check``.
    busy_timeout_s : float
        How long (s) a connection waits for another process' lock.
    group_readable : bool
        Create a new file 0640 instead of 0600.

    Raises
    ------
    StoreError
        The file is empty, not a database, damaged, a symbolic link, or has
        a newer schema.
    """

    def __init__(self, path: str | Path, busy_timeout_s: float = 30.0, group_readable: bool = False):
        self.path = Path(path)
        create_or_check_file(self.path, 0o640 if group_readable else 0o600)
        self._busy_ms = int(busy_timeout_s * 1000)
        self._local = threading.local()
        self._lock = threading.RLock()
        #: held while the outbox is being published, so that two pipelines on one store
        #: (e.g. after a config reload) never publish the same rows at the same time
        self.publish_lock = threading.Lock()
        self._conns: list[sqlite3.Connection] = []
        self._closed = False
        self._started: set[int] = set()  # jobs this process started and has not finished
        self._parked: set[int] = set()  # first plan stored, waiting for an optimisation slot (start given back)
        conn = self.connection()
        try:
            version = conn.execute("PRAGMA user_version").fetchone()[0]
            problems = [r[0] for r in conn.execute("PRAGMA quick_check(5)")]
        except sqlite3.DatabaseError as exc:
            self.close()
            raise StoreError(f"{self.path}: not a usable SQLite database ({exc})") from None
        if problems != ["ok"]:
            self.close()
            raise StoreError(f"{self.path}: damaged SQLite database, PRAGMA quick_check says: "
                             + storable("; ".join(map(str, problems)), 300)
                             + " (restore it from a backup or move it aside)")
        if version > SCHEMA_VERSION:
            raise StoreError(f"{self.path}: schema version {version} is newer than this program's {SCHEMA_VERSION}")
        if version == 0:
            with self._lock:
                # pruned raw bytes go back to the file system (before any table exists; issue 25)
                conn.execute("PRAGMA auto_vacuum=INCREMENTAL")
                conn.execute("VACUUM")  # the file is empty: this only makes the setting take effect
                conn.executescript("BEGIN IMMEDIATE;" + SCHEMA + "COMMIT;")
        self._upgrade(conn, version)

    def _upgrade(self, conn: sqlite3.Connection, version: int) -> None:
        """Apply the :data:`~mushrooms.daemon.state.schema.UPGRADES` the file lacks and set ``user_version`` (one transaction)."""
        if version == SCHEMA_VERSION and not missing_steps(conn):
            return
        with self._lock:
            conn.execute("BEGIN IMMEDIATE")
            try:
                for step in missing_steps(conn):  # again under the write lock: another process may have done it
                    for sql in filter(str.strip, step.split(";")):
                        conn.execute(sql)
                conn.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise
        if 0 < version < SCHEMA_VERSION:
            log.info("state %s migrated from schema %d to %d", self.path, version, SCHEMA_VERSION)

    # ------------------------------------------------------------ connections
    def connection(self) -> sqlite3.Connection:
        """This thread's connection (autocommit; reads see committed state).

        The seam for the modules that own a table of their own
        (:mod:`~mushrooms.daemon.submission.submitter`, :mod:`~mushrooms.daemon.state.executed`, :mod:`~mushrooms.daemon.planning.replans`):
        they read with it and write inside :meth:`transaction`.

        Raises
        ------
        StoreError
            The store is closed, or the file is not a usable database.
        """
        if self._closed:
            raise StoreError(f"{self.path}: store is closed")
        conn = getattr(self._local, "conn", None)
        if conn is None:
            conn = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False,
                                   timeout=self._busy_ms / 1000)
            conn.row_factory = sqlite3.Row
            conn.execute(f"PRAGMA busy_timeout={self._busy_ms}")
            try:
                conn.execute("PRAGMA journal_mode=WAL")
            except sqlite3.DatabaseError as exc:
                conn.close()
                raise StoreError(f"{self.path}: not a usable SQLite database ({exc})") from None
            conn.execute("PRAGMA synchronous=FULL")
            conn.execute("PRAGMA foreign_keys=ON")
            self._local.conn = conn
            with self._lock:
                self._conns.append(conn)
        return conn

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction (BEGIN IMMEDIATE ... COMMIT, ROLLBACK on error).

        Inside a transaction of the same thread it joins that transaction.
        """
        conn = self.connection()
        with self._lock:
            if conn.in_transaction:  # nested use inside a transaction of this thread
                yield conn
                return
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
            except BaseException:
                conn.execute("ROLLBACK")
                raise
            else:
                conn.execute("COMMIT")

    def close(self) -> None:
        """Close every thread's connection (checkpointing the WAL)."""
        with self._lock:
            self._closed = True
            for c in self._conns:
                try:
                    c.close()
                except sqlite3.Error:
                    pass
            self._conns.clear()

    @property
    def closed(self) -> bool:
        """True once :meth:`close` ran (every call then raises :class:`StoreError`)."""
        return self._closed

    # ------------------------------------------------------------ ledger
    def event_state(self, superevent_id: str) -> EventState | None:
        """State of a superevent (the handlers' ``Ledger`` protocol)."""
        return current_event.event_state(self.connection(), superevent_id)

    # ------------------------------------------------------------ accept
    def record_rejected(self, notice: NoticeRecord, reason: str) -> int:
        """Record a notice that could not be parsed; returns its notice_id.

        Of its raw bytes only the first :data:`RAW_PREFIX_BYTES` are kept
        (its SHA-256 and size say the rest), until :meth:`prune_raw`.
        """
        if notice.raw is not None and len(notice.raw) > RAW_PREFIX_BYTES:
            notice = NoticeRecord(notice.origin, notice.sha256, notice.size, notice.received_at,
                                  notice.superevent_id, notice.alert_type, notice.time_created,
                                  notice.raw[:RAW_PREFIX_BYTES])
        with self.transaction() as c:
            nid = self._insert_notice(c, notice)
            c.execute("INSERT INTO decisions(notice_id, superevent_id, alert_type, decision, reason, created_at)"
                      " VALUES (?,?,?,?,?,?)",
                      (nid, _opt(notice.superevent_id), _opt(notice.alert_type), "rejected", storable(reason),
                       now_iso()))
        return nid

    def prune_raw(self, older_than_s: float, planned_older_than_s: float | None = None) -> int:
        """Forget raw bytes no longer needed; returns how many notices lost theirs.

        * Rejected messages: their first KiB, once decided more than
          ``older_than_s`` (s) ago.
        * Planned notices (with ``planned_older_than_s``): once none of the
          notice's jobs is open (a job re-reads its sky map from the bytes
          after a crash), at once when it is neither its event's current
          map nor its current plan's notice (:mod:`~mushrooms.daemon.state.current_event` C3),
          else (re-plans and ``mushrooms trigger SUPEREVENT`` read them)
          when its last job finished more than ``planned_older_than_s`` (s) ago.

        On a state file created with incremental auto-vacuum (every file
        this version creates) the freed pages go back to the file system;
        on older files SQLite reuses them.
        """
        def cutoff(age_s: float) -> str:
            return datetime.fromtimestamp(time.time() - age_s, timezone.utc).isoformat(timespec="milliseconds")

        with self.transaction() as c:
            cur = c.execute(
                "UPDATE notices SET raw=NULL WHERE raw IS NOT NULL AND notice_id IN"
                " (SELECT notice_id FROM decisions WHERE decision='rejected' AND created_at<=?)"
                " AND notice_id NOT IN (SELECT notice_id FROM jobs)", (cutoff(older_than_s),))
            n = int(cur.rowcount)
            if planned_older_than_s is not None:
                kept = json.dumps(sorted(current_event.kept_notices(c)))  # (C3)
                cur = c.execute(
                    "WITH per_notice AS (SELECT notice_id, SUM(status IN ('pending','running')) AS open_jobs,"
                    "   MAX(COALESCE(finished_at, created_at)) AS last_done FROM jobs GROUP BY notice_id)"
                    " UPDATE notices SET raw=NULL WHERE raw IS NOT NULL AND notice_id IN"
                    " (SELECT notice_id FROM per_notice WHERE open_jobs=0 AND (last_done<=?"
                    "  OR notice_id NOT IN (SELECT value FROM json_each(?))))",
                    (cutoff(planned_older_than_s), kept))
                n += int(c.execute("SELECT changes()").fetchone()[0])  # rowcount is -1 for WITH ... UPDATE
        if n:
            try:
                with self._lock:  # executescript steps the pragma to the end (execute frees one page)
                    self.connection().executescript("PRAGMA incremental_vacuum;")
            except sqlite3.Error as exc:  # reclaiming space is a courtesy
                log.warning("state %s: incremental_vacuum failed: %s", self.path, exc)
        return n

    def record_decision(
        self,
        notice: NoticeRecord,
        decide: Callable[[_TxLedger], Decision],
        start: Callable[[Decision], str | None],
        received_wall: float,
        withdrawal: Callable[[Decision, int], dict[str, Any]] | None = None,
    ) -> tuple[int, Decision, Job | None, list[int], str | None]:
        """Read the superevent state, decide and record it, atomically.

        Parameters
        ----------
        notice : NoticeRecord
            The parsed notice (raw bytes are kept only when a job needs them).
        decide : callable
            ``decide(ledger) -> Decision`` run inside the transaction.
        start : callable
            Horizon start (ISO UTC) for a planning decision; None turns the
            decision into ``rejected`` (nothing to plan from).
        received_wall : float
            Unix time (s) of receipt.
        withdrawal : callable, optional
            ``withdrawal(decision, notice_id) -> message`` for a ``withdraw``.

        Returns
        -------
        notice_id, decision, job, cancelled_job_ids, outbox_key
        """
        with self.transaction() as c:
            decision = decide(_TxLedger(c))
            job: Job | None = None
            cancelled: list[int] = []
            key: str | None = None
            begin = start(decision) if decision.needs_plan else None
            if decision.needs_plan and begin is None:
                decision = Decision("rejected", decision.superevent_id, "no sky map bytes to plan from "
                                    "(VOEvent sky maps are URLs; fetching is not supported)", decision.alert_type)
            keep_raw = decision.needs_plan
            nid = self._insert_notice(c, notice if keep_raw else without_raw(notice))
            now = now_iso()
            sid = decision.superevent_id
            if decision.needs_plan:
                cancelled = [r[0] for r in c.execute(
                    "SELECT job_id FROM jobs WHERE superevent_id=? AND status IN ('pending','running')", (sid,))]
                c.execute("UPDATE jobs SET status='superseded', reason='newer sky map', finished_at=?"
                          " WHERE superevent_id=? AND status IN ('pending','running')", (now, sid))
                c.execute("INSERT INTO events(superevent_id, skymap_sha256, retracted, updated_at, localization)"
                          " VALUES (?,?,0,?,?) ON CONFLICT(superevent_id) DO UPDATE SET"
                          " skymap_sha256=excluded.skymap_sha256, retracted=0, updated_at=excluded.updated_at,"
                          " localization=excluded.localization", (sid, decision.skymap_sha256, now,
                                                                   decision.localization))
                cur = c.execute(
                    "INSERT INTO jobs(notice_id, superevent_id, alert_type, time_created, skymap_sha256, decision,"
                    " start, supersedes, received_wall, status, created_at) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
                    (nid, sid, decision.alert_type, notice.time_created, decision.skymap_sha256,
                     decision.action, begin, decision.supersedes, received_wall, "pending", now))
                row = c.execute("SELECT * FROM jobs WHERE job_id=?", (cur.lastrowid,)).fetchone()
                job = job_from_row(row)
            elif decision.action == "withdraw":
                cancelled = [r[0] for r in c.execute(
                    "SELECT job_id FROM jobs WHERE superevent_id=? AND status IN ('pending','running')", (sid,))]
                c.execute("UPDATE jobs SET status='cancelled', reason='retracted', finished_at=?"
                          " WHERE superevent_id=? AND status IN ('pending','running')", (now, sid))
                c.execute("UPDATE plans SET withdrawn=1 WHERE superevent_id=?", (sid,))
                c.execute("UPDATE events SET retracted=1, updated_at=? WHERE superevent_id=?", (now, sid))
                if withdrawal is not None:
                    msg = withdrawal(decision, nid)
                    key = str(msg["withdrawal_id"])
                    self.insert_outbox(c, key, "withdrawal", msg)
            elif decision.retracts_unknown and decision.time_created:
                # a retraction before any notice of its event: remembered, so that an older notice
                # arriving after it is stale (creation order, issue 25); nothing is withdrawn or sent
                c.execute("INSERT INTO events(superevent_id, skymap_sha256, retracted, updated_at, localization,"
                          " latest_created) VALUES (?,NULL,1,?,NULL,?) ON CONFLICT(superevent_id) DO NOTHING",
                          (sid, now, decision.time_created))
            if decision.accepted and decision.time_created:
                self._note_created(c, sid, decision.time_created)
            c.execute("INSERT INTO decisions(notice_id, superevent_id, alert_type, decision, reason, job_id,"
                      " created_at) VALUES (?,?,?,?,?,?,?)",
                      (nid, _opt(sid), _opt(decision.alert_type), decision.action, storable(decision.reason),
                       job.job_id if job else None, now))
        return nid, decision, job, cancelled, key

    @staticmethod
    def _note_created(c: sqlite3.Connection, sid: str, created: str) -> None:
        """Keep the event's newest accepted ``time_created`` (the creation order of its notices)."""
        row = c.execute("SELECT latest_created FROM events WHERE superevent_id=?", (sid,)).fetchone()
        if row is not None:
            c.execute("UPDATE events SET latest_created=? WHERE superevent_id=?",
                      (newest_created(row[0], created), sid))

    @staticmethod
    def _insert_notice(c: sqlite3.Connection, n: NoticeRecord) -> int:
        cur = c.execute(
            "INSERT INTO notices(received_at, origin, sha256, size, superevent_id, alert_type, time_created, raw)"
            " VALUES (?,?,?,?,?,?,?,?)",
            (n.received_at, storable(n.origin), n.sha256, n.size, _opt(n.superevent_id), _opt(n.alert_type),
             _opt(n.time_created), n.raw))
        return int(cur.lastrowid)

    @staticmethod
    def insert_outbox(c: sqlite3.Connection, key: str, kind: str, message: dict[str, Any]) -> int:
        """Queue a message to publish inside the caller's transaction ``c``; returns its outbox id."""
        cur = c.execute("INSERT INTO outbox(key, kind, body, created_at) VALUES (?,?,?,?)",
                        (key, kind, strict_json.dumps(message, sort_keys=False), now_iso()))
        return int(cur.lastrowid)

    # ------------------------------------------------------------ jobs
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
            if row is None or row["status"] not in _OPEN:
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
        return str(row[0]) + (f" ({row[1]})" if row[1] and row[0] in ("failed", "superseded", "cancelled") else "")

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
            if row is None or row["status"] != "running":
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
            if row is None or row["status"] != "running":
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

    # ------------------------------------------------------------ outbox
    def pending_outbox(self, limit: int = 1000) -> list[OutboxMessage]:
        """Messages not yet published, oldest first."""
        rows = self.connection().execute(
            "SELECT * FROM outbox WHERE published_at IS NULL ORDER BY outbox_id LIMIT ?", (limit,)).fetchall()
        return [OutboxMessage(r["outbox_id"], r["key"], r["kind"], json.loads(r["body"]), r["attempts"], None,
                              r["created_at"]) for r in rows]

    def mark_published(self, outbox_id: int) -> None:
        with self.transaction() as c:
            c.execute("UPDATE outbox SET published_at=?, attempts=attempts+1, last_error=NULL WHERE outbox_id=?",
                      (now_iso(), outbox_id))

    def mark_publish_failed(self, outbox_id: int, error: str) -> None:
        with self.transaction() as c:
            c.execute("UPDATE outbox SET attempts=attempts+1, last_error=? WHERE outbox_id=?",
                      (storable(error, 500), outbox_id))

    # ------------------------------------------------------------ incidents
    def record_incident(self, kind: str, detail: dict[str, Any]) -> int:
        """Keep a small record of something the operator must hear of (``mushrooms status`` shows it)."""
        with self.transaction() as c:
            return int(c.execute("INSERT INTO incidents(kind, detail, created_at) VALUES (?,?,?)",
                                 (kind, json.dumps(detail), now_iso())).lastrowid)

    def received_wall(self, plan_id: str) -> float | None:
        """When the notice of the job that made ``plan_id`` was received (Unix s), or None."""
        row = self.connection().execute("SELECT j.received_wall FROM plans p JOIN jobs j USING(job_id)"
                                   " WHERE p.plan_id=?", (plan_id,)).fetchone()
        return None if row is None else float(row[0])

    # ------------------------------------------------------------ inspection
    def decisions(self) -> list[dict[str, Any]]:
        """Every decision, oldest first (for tests and operators)."""
        rows = self.connection().execute(
            "SELECT d.*, n.origin, j.status AS job_status, j.plan_id FROM decisions d"
            " JOIN notices n USING(notice_id) LEFT JOIN jobs j USING(job_id) ORDER BY decision_id").fetchall()
        return [dict(r) for r in rows]

    def plans(self, superevent_id: str | None = None) -> list[dict[str, Any]]:
        """Stored plans (documents parsed), oldest first."""
        q = "SELECT plan_id, superevent_id, job_id, created_at, withdrawn, revision, final, document FROM plans"
        args: tuple[Any, ...] = ()
        if superevent_id is not None:
            q += " WHERE superevent_id=?"
            args = (superevent_id,)
        rows = self.connection().execute(q + " ORDER BY seq", args).fetchall()
        return [dict(r) | {"document": json.loads(r["document"])} for r in rows]

    def counts(self) -> dict[str, int]:
        """Row counts and open work (for the heartbeat)."""
        c = self.connection()
        out = {t: c.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]
               for t in ("notices", "decisions", "events", "jobs", "plans", "outbox")}
        out["jobs_open"] = c.execute("SELECT COUNT(*) FROM jobs WHERE status IN ('pending','running')").fetchone()[0]
        out["outbox_pending"] = c.execute("SELECT COUNT(*) FROM outbox WHERE published_at IS NULL").fetchone()[0]
        return out


def _opt(text: str | None) -> str | None:
    return None if text is None else storable(text)


def sha256_hex(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def wall_time() -> float:
    return time.time()
