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
from ...handlers.text import storable
from ...scheduler_core.plan import strict_json
from ...scheduler_core.plan.messages import plan_final_message
from . import current_event
from .file import StateInUse, StateLock, StoreError, create_or_check_file, lock_state
from .job_rows import FALLBACK_ATTEMPTS, JobRows
from .records import Job, JobState, NoticeRecord, OutboxMessage, job_from_row, now_iso, without_raw
from .schema import SCHEMA, SCHEMA_VERSION, missing_steps

__all__ = ["Store", "StoreError", "StateInUse", "StateLock", "lock_state", "Job", "OutboxMessage", "NoticeRecord",
           "SCHEMA_VERSION", "RAW_PREFIX_BYTES", "FALLBACK_ATTEMPTS", "plan_final_message"]

log = logging.getLogger("mushrooms.daemon.store")

#: Bytes kept of a rejected message (with its SHA-256 and size): enough to see what it was.
RAW_PREFIX_BYTES = 1024


class _TxLedger:
    """Ledger view over one open transaction."""

    def __init__(self, conn: sqlite3.Connection):
        self.conn = conn

    def event_state(self, superevent_id: str) -> EventState | None:
        return current_event.event_state(self.conn, superevent_id)


class Store(JobRows):
    """SQLite state of the service; implements the handlers' ``Ledger``.

    The jobs' rows are :class:`~mushrooms.daemon.state.job_rows.JobRows`'.

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
        self.init_job_rows()
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
                # pruned raw bytes go back to the file system (before any table exists)
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
                cancelled = self._end_open_jobs(c, sid, JobState.SUPERSEDED, "newer sky map", now)
                job = self._insert_job(c, decision, nid, notice, begin, received_wall, now)
            elif decision.action == "withdraw":
                cancelled = self._end_open_jobs(c, sid, JobState.CANCELLED, "retracted", now)
                c.execute("UPDATE plans SET withdrawn=1 WHERE superevent_id=?", (sid,))
                c.execute("UPDATE events SET retracted=1, updated_at=? WHERE superevent_id=?", (now, sid))
                if withdrawal is not None:
                    msg = withdrawal(decision, nid)
                    key = str(msg["withdrawal_id"])
                    self.insert_outbox(c, key, "withdrawal", msg)
            elif decision.retracts_unknown and decision.time_created:
                # a retraction before any notice of its event: remembered, so that an older notice
                # arriving after it is stale (creation order); nothing is withdrawn or sent
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
    def _end_open_jobs(c: sqlite3.Connection, sid: str, status: JobState, reason: str, now: str) -> list[int]:
        """End the event's open jobs (``superseded`` by a newer map, ``cancelled`` by a retraction); their ids."""
        ended = [r[0] for r in c.execute(
            "SELECT job_id FROM jobs WHERE superevent_id=? AND status IN ('pending','running')", (sid,))]
        c.execute("UPDATE jobs SET status=?, reason=?, finished_at=?"
                  " WHERE superevent_id=? AND status IN ('pending','running')", (status, reason, now, sid))
        return ended

    @staticmethod
    def _insert_job(c: sqlite3.Connection, decision: Decision, nid: int, notice: NoticeRecord, begin: str | None,
                    received_wall: float, now: str) -> Job:
        """The event's new map: remember it and queue its planning job (``pending``)."""
        sid = decision.superevent_id
        c.execute("INSERT INTO events(superevent_id, skymap_sha256, retracted, updated_at, localization)"
                  " VALUES (?,?,0,?,?) ON CONFLICT(superevent_id) DO UPDATE SET"
                  " skymap_sha256=excluded.skymap_sha256, retracted=0, updated_at=excluded.updated_at,"
                  " localization=excluded.localization", (sid, decision.skymap_sha256, now, decision.localization))
        cur = c.execute(
            "INSERT INTO jobs(notice_id, superevent_id, alert_type, time_created, skymap_sha256, decision,"
            " start, supersedes, received_wall, status, created_at) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
            (nid, sid, decision.alert_type, notice.time_created, decision.skymap_sha256,
             decision.action, begin, decision.supersedes, received_wall, JobState.PENDING, now))
        return job_from_row(c.execute("SELECT * FROM jobs WHERE job_id=?", (cur.lastrowid,)).fetchone())

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
