"""What the store hands out: jobs, outbox messages, received notices, event references (small frozen records).

:func:`job_from_row` reads a ``jobs`` row; :func:`now_iso` is the store's
timestamp (ISO-8601 UTC, milliseconds).
"""

from __future__ import annotations

import enum
import sqlite3
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any


__all__ = ["EventRef", "Job", "JobState", "OPEN_JOBS", "OutboxMessage", "NoticeRecord", "job_from_row", "without_raw", "now_iso"]


@dataclass(frozen=True)
class EventRef:
    """Which superevent, notice and job a result is about.

    Attributes
    ----------
    superevent_id, alert_type : str or None
    notice_id, job_id : int or None
        Store ids.
    """

    superevent_id: str | None = None
    alert_type: str | None = None
    notice_id: int | None = None
    job_id: int | None = None



class JobState(enum.StrEnum):
    """A planning job's ``status`` in the ``jobs`` table (the stored text is the value).

    ``pending`` -> ``running`` -> ``done`` | ``failed`` | ``superseded`` |
    ``cancelled``; a clean stop puts a running job back to ``pending``.
    """

    PENDING = "pending"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    SUPERSEDED = "superseded"  # a newer sky map of the event
    CANCELLED = "cancelled"  # the event was retracted


#: States of a job that is not finished (it runs again at the next start).
OPEN_JOBS = (JobState.PENDING, JobState.RUNNING)


def now_iso() -> str:
    """Now, ISO-8601 UTC with milliseconds (the store's timestamps)."""
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


@dataclass(frozen=True)
class Job:
    """A planning job accepted but maybe not finished.

    Attributes
    ----------
    job_id : int
        Store id (stable across restarts).
    notice_id : int
        The notice whose sky map is planned (raw bytes kept in the store).
    superevent_id, alert_type : str
    time_created : str or None
        The notice's ``time_created`` (ISO-8601 UTC).
    skymap_sha256 : str
    decision : str
        ``plan`` or ``rerun``.
    start : str
        Horizon start (ISO-8601 UTC), fixed at accept time.
    supersedes : str or None
        Plan this job replaces (set when the job starts).
    received_wall : float
        Unix time (s) the notice was received: latency is measured from it.
    attempts : int
        Starts that died (a crash or kill leaves the job ``running``; a
        clean stop gives the start back, :meth:`Store.release_unfinished`).
    status : str
    fallback : bool
        Set by :meth:`Store.start_job` when the optimiser died too often:
        this run uses the fast scheduler only (degrade, never drop).
    """

    job_id: int
    notice_id: int
    superevent_id: str
    alert_type: str
    time_created: str | None
    skymap_sha256: str
    decision: str
    start: str
    supersedes: str | None
    received_wall: float
    attempts: int
    status: str
    fallback: bool = False

    @property
    def ref(self) -> EventRef:
        """The job's event, notice and job ids (what every :class:`~mushrooms.daemon.outcomes.Outcome` of it carries)."""
        return EventRef(self.superevent_id, self.alert_type, self.notice_id, self.job_id)


@dataclass(frozen=True)
class OutboxMessage:
    """A message waiting in (or published from) the outbox."""

    outbox_id: int
    key: str
    kind: str
    message: dict[str, Any]
    attempts: int
    published_at: str | None
    created_at: str | None = None


@dataclass(frozen=True)
class NoticeRecord:
    """What is stored about one received message (before or without parsing)."""

    origin: str
    sha256: str
    size: int
    received_at: str
    superevent_id: str | None = None
    alert_type: str | None = None
    time_created: str | None = None
    raw: bytes | None = None


def job_from_row(row: sqlite3.Row, fallback: bool = False) -> Job:
    """The :class:`Job` of a ``jobs`` row (``fallback``: see :attr:`Job.fallback`)."""
    return Job(
        job_id=row["job_id"], notice_id=row["notice_id"], superevent_id=row["superevent_id"],
        alert_type=row["alert_type"], time_created=row["time_created"],
        skymap_sha256=row["skymap_sha256"], decision=row["decision"], start=row["start"],
        supersedes=row["supersedes"], received_wall=row["received_wall"],
        attempts=row["attempts"], status=row["status"], fallback=fallback,
    )


def without_raw(n: NoticeRecord) -> NoticeRecord:
    """``n`` without its raw bytes."""
    return NoticeRecord(n.origin, n.sha256, n.size, n.received_at, n.superevent_id, n.alert_type,
                        n.time_created, None)
