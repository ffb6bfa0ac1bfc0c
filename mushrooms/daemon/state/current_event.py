"""The event's current map, plan, notice and follow-up start: one answer, asked by every part of the daemon.

What "the event's current ..." means is decided here and nowhere else (the
ledger's :class:`~mushrooms.handlers.decisions.EventState`, the loop, the
re-plans, the nights, ``mushrooms trigger SUPEREVENT``, the raw-byte pruning
and the submitter all read it from these functions):

(C1) **Current plan**: the event's newest plan (``plans.seq``) not withdrawn;
     an event retracted has none for the loop (:func:`live_events`).
(C2) **Current map**: the sky map of the event's newest job that still counts
     (``pending``, ``running`` or ``done``); a job that ``failed``, or was
     ``superseded`` or ``cancelled``, left no map.  A re-plan job carries the
     notice of the map it re-planned, so a map stays current through its
     re-plans; a newer sky map's open job is the current map even before it
     produced a plan (an operator's closure then re-plans *that* map, never
     the older one of the current plan).
(C3) **Kept notices**: a planned notice keeps its raw bytes while a job of it
     is open, and while it is the current map's or the current plan's notice
     (a re-plan, a night re-plan or ``trigger SUPEREVENT`` reads the map from
     them); only these two may lose them once their last job finished more
     than ``[daemon] keep_planned_raw_days`` ago (:meth:`Store.prune_raw`).
(C4) **Follow-up start**: the earliest horizon start of the event's jobs;
     executed exposures before it are not this event's, and its nights count
     from it.

Every function takes a connection (the store's, or one inside a write
transaction), so a decision and the state it was made on are one snapshot.
"""

from __future__ import annotations

import json
import sqlite3
from typing import Any

from ...handlers.decisions import EventState
from .records import JobState

__all__ = ["COUNTING", "current_plan", "map_job", "open_jobs", "live_events", "event_state", "planned_notice",
           "kept_notices", "first_start", "latest_plan_id", "asked_at"]

#: Job states whose sky map still counts (C2).
COUNTING = (JobState.PENDING, JobState.RUNNING, JobState.DONE)


def latest_plan_id(conn: sqlite3.Connection, superevent_id: str) -> str | None:
    """(C1) The id of the event's newest plan not withdrawn (retracted or not), or None.

    Plans stored without a superevent (a bare sky map of an old file) are
    their own event: ``COALESCE(superevent_id, plan_id)``.
    """
    row = conn.execute("SELECT plan_id FROM plans WHERE COALESCE(superevent_id, plan_id)=? AND withdrawn=0"
                       " ORDER BY seq DESC LIMIT 1", (superevent_id,)).fetchone()
    return None if row is None else str(row[0])


def current_plan(conn: sqlite3.Connection, superevent_id: str, live: bool = False) -> dict[str, Any] | None:
    """(C1) The event's current plan: ``plan_id``, ``job_id``, ``revision``, ``seq``, ``document`` (parsed).

    With ``live`` a retracted event has none.
    """
    row = conn.execute(
        "SELECT p.plan_id, p.job_id, p.revision, p.seq, p.document FROM plans p LEFT JOIN events e"
        " USING(superevent_id) WHERE p.superevent_id=? AND p.withdrawn=0"
        + (" AND COALESCE(e.retracted, 0)=0" if live else "") + " ORDER BY p.seq DESC LIMIT 1",
        (superevent_id,)).fetchone()
    return None if row is None else dict(row) | {"document": json.loads(row["document"])}


def map_job(conn: sqlite3.Connection, superevent_id: str) -> sqlite3.Row | None:
    """(C2) The ``jobs`` row whose sky map is the event's current one (newest pending, running or done), or None."""
    return conn.execute("SELECT * FROM jobs WHERE superevent_id=? AND status IN (?,?,?) ORDER BY job_id DESC"
                        " LIMIT 1", (superevent_id, *COUNTING)).fetchone()


def open_jobs(conn: sqlite3.Connection, superevent_id: str) -> list[int]:
    """Ids of the event's jobs not finished (``pending``, ``running``), oldest first."""
    return [int(r[0]) for r in conn.execute("SELECT job_id FROM jobs WHERE superevent_id=? AND status IN"
                                            " ('pending','running') ORDER BY job_id", (superevent_id,))]


def live_events(conn: sqlite3.Connection) -> list[str]:
    """(C1) Superevents with a current plan and no retraction, in the order their current plans were stored."""
    rows = conn.execute(
        "SELECT p.superevent_id, MAX(p.seq) AS last FROM plans p JOIN events e USING(superevent_id)"
        " WHERE p.withdrawn=0 AND e.retracted=0 GROUP BY p.superevent_id ORDER BY last").fetchall()
    return [str(r[0]) for r in rows]


def event_state(conn: sqlite3.Connection, superevent_id: str) -> EventState | None:
    """The ledger's view of an event (the handlers' ``decide`` reads it), or None when it was never heard of."""
    row = conn.execute("SELECT skymap_sha256, retracted, localization, latest_created FROM events"
                       " WHERE superevent_id=?", (superevent_id,)).fetchone()
    if row is None:
        return None
    ids = tuple(r[0] for r in conn.execute(
        "SELECT plan_id FROM plans WHERE superevent_id=? AND withdrawn=0 ORDER BY seq", (superevent_id,)))
    return EventState(superevent_id, row[0], ids, bool(row[1]), localization=row[2],
                      open_job=bool(open_jobs(conn, superevent_id)), latest_created=row[3])


def planned_notice(conn: sqlite3.Connection, superevent_id: str) -> tuple[int, bytes] | None:
    """(C2) The current map's notice with its raw bytes (``trigger SUPEREVENT`` plans it again).

    When the current map's bytes are gone (pruned after
    ``keep_planned_raw_days``), the current plan's notice, then the newest
    planned notice that still has bytes; None when no notice of the event has.
    """
    for job in (map_job(conn, superevent_id), _plan_job(conn, superevent_id)):
        if job is not None:
            raw = conn.execute("SELECT raw FROM notices WHERE notice_id=?", (job["notice_id"],)).fetchone()
            if raw is not None and raw[0] is not None:
                return int(job["notice_id"]), bytes(raw[0])
    row = conn.execute(
        "SELECT n.notice_id, n.raw FROM jobs j JOIN notices n USING(notice_id) WHERE j.superevent_id=?"
        " AND n.raw IS NOT NULL ORDER BY j.job_id DESC LIMIT 1", (superevent_id,)).fetchone()
    return None if row is None else (int(row[0]), bytes(row[1]))


def _plan_job(conn: sqlite3.Connection, superevent_id: str) -> sqlite3.Row | None:
    """The ``jobs`` row that made the event's current plan (None for a plan without a job)."""
    plan = current_plan(conn, superevent_id)
    if plan is None or plan["job_id"] is None:
        return None
    return conn.execute("SELECT * FROM jobs WHERE job_id=?", (plan["job_id"],)).fetchone()


def kept_notices(conn: sqlite3.Connection) -> set[int]:
    """(C3) Notices that are some event's current map or current plan (kept until their age runs out)."""
    kept = {int(r[0]) for r in conn.execute(
        "SELECT j.notice_id FROM jobs j JOIN (SELECT superevent_id, MAX(job_id) AS job_id FROM jobs"
        " WHERE status IN (?,?,?) GROUP BY superevent_id) m USING(job_id)", COUNTING)}
    kept |= {int(r[0]) for r in conn.execute(
        "SELECT j.notice_id FROM jobs j JOIN plans p ON p.job_id=j.job_id JOIN (SELECT superevent_id,"
        " MAX(seq) AS seq FROM plans WHERE withdrawn=0 GROUP BY superevent_id) c ON c.seq=p.seq")}
    return kept


def first_start(conn: sqlite3.Connection, *superevent_ids: str) -> str | None:
    """(C4) The earliest horizon start (ISO-8601 UTC) of these events' jobs, or None when they have none."""
    if not superevent_ids:
        return None
    row = conn.execute(f"SELECT MIN(start) FROM jobs WHERE superevent_id IN ({','.join('?' * len(superevent_ids))})",
                       superevent_ids).fetchone()
    return None if row is None or row[0] is None else str(row[0])


def asked_at(conn: sqlite3.Connection, job_id: int) -> float | None:
    """Unix time the job was asked for: the receipt of the notice (or re-plan request) its decision records.

    An operator's closure is asked for at the closing, its job starts at the
    reopening; None when the job has no decision row (a job of an old file).
    """
    from datetime import datetime, timezone

    row = conn.execute("SELECT n.received_at FROM decisions d JOIN notices n USING(notice_id) WHERE d.job_id=?"
                       " ORDER BY d.decision_id LIMIT 1", (job_id,)).fetchone()
    if row is None or not row[0]:
        return None
    try:
        t = datetime.fromisoformat(str(row[0]).replace("Z", "+00:00"))
    except ValueError:
        return None
    return (t if t.tzinfo else t.replace(tzinfo=timezone.utc)).timestamp()
