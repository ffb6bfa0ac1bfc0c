"""Re-plan jobs of the loop, in the store (``docs/design/executed.md`` L7, L8).

A re-plan is a planning job like any other (the ``jobs`` table, run by the
:class:`~mushrooms.daemon.planning.jobs.JobRunner`'s workers, never on the consume loop) with the
decision ``replan``: it plans the event's newest planned sky map again from
``start`` (now, or the dome's reopening) with what was executed counted as
done, and its plan supersedes the event's current plan as the event's next
revision.  It is recorded like an operator's rerun, in one transaction: a
``notices`` row saying what asked for it (the loop's poll, or ``mushrooms
trigger SUPEREVENT --closed-until``; no raw bytes), the job (on the notice
whose sky map it re-plans) and a ``decisions`` row with the reason.

(L8) Guards: an event is re-planned only when it has a current plan (not
withdrawn, not retracted); the loop re-plans a current plan at most once and
never while a job of the event is open (that job's plan supersedes the old
one anyway); an operator's closure supersedes an open job instead.

(L12) What is re-planned: the event's *current map* (:mod:`~mushrooms.daemon.state.current_event`
C2), which is a newer sky map's open job when there is one (an operator's
closure supersedes that job and re-plans its map from the reopening, never
the older map of the current plan); the re-plan supersedes the current plan
(C1), the queue on the telescope.
"""

from __future__ import annotations

import hashlib
import logging
import time
from typing import Any

from ..state import current_event
from ..outcomes import Accepted, EventRef
from ..state.store import Store
from ..state.records import JobState, job_from_row, now_iso

__all__ = ["record_replan", "close_without_plan", "next_revision", "current_plan", "live_events", "replan_jobs"]

log = logging.getLogger("mushrooms.daemon.loop")


def current_plan(store: Store, superevent_id: str) -> dict[str, Any] | None:
    """The event's newest plan not withdrawn (:func:`~mushrooms.daemon.state.current_event.current_plan`, C1), or None."""
    return current_event.current_plan(store.connection(), superevent_id)


def live_events(store: Store) -> list[str]:
    """Superevents with a current plan and no retraction, in the order their plans were stored (C1)."""
    return current_event.live_events(store.connection())


def next_revision(store: Store, superevent_id: str) -> int:
    """The revision number of the event's next plan: one more than any it stored."""
    row = store.connection().execute("SELECT COALESCE(MAX(revision), 0) + 1 FROM plans WHERE superevent_id=?",
                                (superevent_id,)).fetchone()
    return int(row[0])


def record_replan(store: Store, superevent_id: str, start: str, reason: str, origin: str,
                  operator: bool = False, night: bool = False, asked_at: str | None = None) -> Accepted:
    """Record a re-plan job of an event from ``start``, atomically (guards L8).

    Parameters
    ----------
    store : Store
    superevent_id : str
    start : str
        The new horizon start (ISO-8601 UTC).
    reason : str
        Why (the slip rule's reason, or the operator's closure).
    origin : str
        What asked (``loop:poll``, ``trigger:<file>``).
    operator : bool
        An operator's request: an open job of the event is superseded
        instead of blocking, and an already re-planned plan is re-planned again.
    night : bool
        A later night's re-plan (L10): an already re-planned plan is
        re-planned again (a new night is new work); an open job still blocks.
    asked_at : str, optional
        When it was asked for (ISO-8601 UTC; default now): an operator's
        closure is asked at the closing and starts at the reopening (L14).

    Returns
    -------
    Accepted
        ``replan`` with the job; ``ignore`` when a guard holds (an open job,
        already re-planned); ``rejected`` when the event has no current plan.
    """
    sid = superevent_id.strip()
    ref = EventRef(sid or None)
    with store.transaction() as c:
        plan = current_event.current_plan(c, sid, live=True)  # (C1) the queue the re-plan replaces
        source = None if plan is None else current_event.map_job(c, sid)  # (C2) the map it re-plans
        if source is None:
            why = f"no current plan of {sid!r} to re-plan (never planned, withdrawn or retracted)"
            log.warning("replan superevent_id=%s origin=%s decision=rejected reason=%r", sid or "-", origin, why)
            return Accepted("rejected", ref, why)
        ref = EventRef(sid, source["alert_type"])
        open_jobs = current_event.open_jobs(c, sid)
        why = None
        if open_jobs and not operator:
            why = f"job {open_jobs[-1]} of the event is open; its plan will supersede {plan['plan_id']}"
        elif not operator and not night and c.execute("SELECT 1 FROM jobs WHERE decision='replan' AND supersedes=?",
                                        (plan["plan_id"],)).fetchone():
            why = f"plan {plan['plan_id']} was re-planned already"
        if why is not None:
            log.info("replan superevent_id=%s origin=%s decision=ignore reason=%r", sid, origin, why)
            return Accepted("ignore", ref, why)
        now = now_iso()
        if open_jobs:
            c.execute("UPDATE jobs SET status='superseded', reason='operator closure', finished_at=?"
                      " WHERE superevent_id=? AND status IN ('pending','running')", (now, sid))
        asked = f"replan {sid} from {start}: {reason}"
        nid = int(c.execute(
            "INSERT INTO notices(received_at, origin, sha256, size, superevent_id, alert_type, time_created, raw)"
            " VALUES (?,?,?,?,?,?,?,NULL)", (asked_at or now, origin[:500], hashlib.sha256(asked.encode()).hexdigest(), 0, sid,
                                             source["alert_type"], source["time_created"])).lastrowid)
        cur = c.execute(
            "INSERT INTO jobs(notice_id, superevent_id, alert_type, time_created, skymap_sha256, decision, start,"
            " supersedes, received_wall, status, created_at) VALUES (?,?,?,?,?,?,?,?,?,?,?)",
            (source["notice_id"], sid, source["alert_type"], source["time_created"], source["skymap_sha256"],
             "replan", start, plan["plan_id"], time.time(), JobState.PENDING, now))
        job = job_from_row(c.execute("SELECT * FROM jobs WHERE job_id=?", (cur.lastrowid,)).fetchone())
        c.execute("INSERT INTO decisions(notice_id, superevent_id, alert_type, decision, reason, job_id, created_at)"
                  " VALUES (?,?,?,?,?,?,?)", (nid, sid, source["alert_type"], "replan", reason[:2000], job.job_id,
                                              now))
    log.info("replan superevent_id=%s origin=%s job=%d start=%s supersedes=%s reason=%r%s", sid, origin, job.job_id,
             start, plan["plan_id"], reason, f" cancelled_jobs={','.join(map(str, open_jobs))}" if open_jobs else "")
    return Accepted("replan", EventRef(sid, source["alert_type"], nid, job.job_id), reason, job, tuple(open_jobs))


def close_without_plan(store: Store, job_id: int, reason: str) -> bool:
    """Close a running re-plan job that found nothing left to observe (the current plan stays); False if not running."""
    return store.close_without_plan(job_id, reason)


def replan_jobs(store: Store, superevent_id: str) -> list[dict[str, Any]]:
    """The event's re-plan jobs, oldest first (id, status, start, supersedes, plan_id, reason)."""
    rows = store.connection().execute(
        "SELECT job_id, status, start, supersedes, plan_id, reason FROM jobs WHERE superevent_id=?"
        " AND decision='replan' ORDER BY job_id", (superevent_id,)).fetchall()
    return [dict(r) for r in rows]
