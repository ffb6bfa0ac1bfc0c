"""Read-only views of the state file, for ``mushrooms status`` and the metrics scrape.

Everything here opens the SQLite file with a ``file:...?mode=ro`` URI: it
never writes the database, never takes a write lock and never creates the
file, so it is safe while the daemon runs (WAL mode: readers see the last
committed state and never block the writer).  When no daemon has the file
open, SQLite may create its empty ``-wal`` and ``-shm`` companions (with the
database file's permissions), which the next daemon start reuses.  A table this program does not know yet (the
``submissions`` on an older file, ``incidents`` on a file no
daemon of this version opened) is simply absent from the answer.
"""

from __future__ import annotations

import json
import sqlite3
from datetime import datetime, timezone
from pathlib import Path
from typing import Any
from urllib.parse import quote

__all__ = ["connect_readonly", "outbox_backlog", "oldest_pending_submission", "recent_events", "attention", "incidents", "has_table",
           "parse_iso", "broker_reachability", "warm_up_plan"]


def connect_readonly(path: str | Path, timeout_s: float = 5.0) -> sqlite3.Connection:
    """A read-only connection to the state file (raises ``sqlite3.OperationalError`` if it does not exist)."""
    p = Path(path).resolve()
    conn = sqlite3.connect(f"file:{quote(str(p))}?mode=ro", uri=True, timeout=timeout_s, check_same_thread=False)
    conn.row_factory = sqlite3.Row
    conn.execute(f"PRAGMA busy_timeout={int(timeout_s * 1000)}")
    return conn


def parse_iso(text: str | None) -> datetime | None:
    """An ISO-8601 time of the store (``...Z`` or ``+00:00``) as an aware datetime; None when absent or bad.

    :func:`mushrooms.handlers.instants.parse_instant`'s twin, kept here so that
    ``mushrooms status`` does not import the handlers package (~1 s).
    """
    if not text:
        return None
    try:
        t = datetime.fromisoformat(text)
    except ValueError:
        return None
    return t if t.tzinfo else t.replace(tzinfo=timezone.utc)


def _age_s(text: str | None, now: datetime) -> float | None:
    t = parse_iso(text)
    return None if t is None else max(0.0, (now - t).total_seconds())


def has_table(conn: sqlite3.Connection, name: str) -> bool:
    """Whether the state file has table ``name``."""
    return conn.execute("SELECT 1 FROM sqlite_master WHERE type='table' AND name=?", (name,)).fetchone() is not None


def outbox_backlog(conn: sqlite3.Connection, now: datetime | None = None) -> tuple[int, float | None, str | None]:
    """(messages not yet published, age in s of the oldest, its last publish error)."""
    now = now or datetime.now(timezone.utc)
    n = conn.execute("SELECT COUNT(*) FROM outbox WHERE published_at IS NULL").fetchone()[0]
    row = conn.execute("SELECT created_at, last_error FROM outbox WHERE published_at IS NULL"
                       " ORDER BY outbox_id LIMIT 1").fetchone()
    if row is None:
        return int(n), None, None
    return int(n), _age_s(row["created_at"], now), row["last_error"]


def incidents(conn: sqlite3.Connection, kind: str | None = None, limit: int = 50) -> list[dict[str, Any]]:
    """Recorded incidents (e.g. ``offset_jump``), newest first; [] on a file without the table."""
    if not has_table(conn, "incidents"):
        return []
    q, args = "SELECT * FROM incidents", ()
    if kind is not None:
        q, args = q + " WHERE kind=?", (kind,)
    rows = conn.execute(q + " ORDER BY incident_id DESC LIMIT ?", args + (limit,)).fetchall()
    return [dict(r) | {"detail": _loads(r["detail"])} for r in rows]


def broker_reachability(conn: sqlite3.Connection) -> dict[str, dict[str, Any]]:
    """What the daemon last recorded of each Kafka client's broker: ``{client: {up, since, error, recorded_at}}``.

    From the newest incident of kind ``broker`` per client
    (:mod:`mushrooms.daemon.ops.broker_record`); {} when none was recorded.
    """
    out: dict[str, dict[str, Any]] = {}
    for inc in incidents(conn, "broker", limit=200):
        d = inc["detail"] if isinstance(inc["detail"], dict) else {}
        client = str(d.get("client") or "?")
        if client not in out:
            out[client] = {"up": bool(d.get("up")), "since": d.get("since"), "error": d.get("error"),
                           "recorded_at": inc["created_at"]}
    return out


def warm_up_plan(conn: sqlite3.Connection) -> dict[str, Any] | None:
    """What the daemon last recorded of its warm-up plan: ``{failed, error, since, recorded_at}``, None when nothing.

    The newest incident of kind ``warm_up_plan`` (:mod:`mushrooms.daemon.ops.warm_record`).
    """
    for inc in incidents(conn, "warm_up_plan", limit=1):
        d = inc["detail"] if isinstance(inc["detail"], dict) else {}
        return {"failed": bool(d.get("failed")), "error": d.get("error"), "since": d.get("since"),
                "recorded_at": inc["created_at"]}
    return None


def _loads(text: str | None) -> Any:
    try:
        return json.loads(text) if text else {}
    except ValueError:
        return {"text": text}


#: The ``submissions`` columns ``mushrooms status`` shows (:data:`~mushrooms.daemon.state.schema.SUBMISSIONS`).
_SUBMISSION_COLUMNS = ("state", "queue_name", "reason", "attempts", "attempted_at", "submitted_at", "finished_at")


def _submissions(conn: sqlite3.Connection) -> dict[str, dict[str, Any]]:
    """plan_id -> its submission row (one per plan id), when the state file has a ``submissions`` table."""
    if not has_table(conn, "submissions"):
        return {}
    cols = {r[1] for r in conn.execute("PRAGMA table_info(submissions)")}
    if "plan_id" not in cols or "state" not in cols:
        return {}
    shown = [c for c in _SUBMISSION_COLUMNS if c in cols]
    return {str(r["plan_id"]): {c: r[c] for c in shown}
            for r in conn.execute(f"SELECT plan_id, {', '.join(shown)} FROM submissions ORDER BY created_at")}


def recent_events(conn: sqlite3.Connection, limit: int = 10) -> list[dict[str, Any]]:
    """The ``limit`` superevents heard from most recently, newest first.

    Each: ``superevent_id``, ``last_received``, ``alert_types`` (in order
    of receipt, repeats removed), ``decision`` and ``reason`` of its newest
    notice, ``jobs`` (id, status, reason), ``plans`` (plan_id, revision,
    final, withdrawn, type, coverage, expected_detections, published,
    submission) and ``retracted``.
    """
    sids = [r[0] for r in conn.execute(
        "SELECT superevent_id FROM notices WHERE superevent_id IS NOT NULL GROUP BY superevent_id"
        " ORDER BY MAX(notice_id) DESC LIMIT ?", (limit,))]
    submissions = _submissions(conn)
    published = {r[0]: r[1] for r in conn.execute(
        "SELECT key, MAX(published_at IS NOT NULL) FROM outbox GROUP BY key")}
    out = []
    for sid in sids:
        notes = conn.execute("SELECT n.notice_id, n.received_at, n.alert_type, d.decision, d.reason FROM notices n"
                             " LEFT JOIN decisions d USING(notice_id) WHERE n.superevent_id=? ORDER BY n.notice_id",
                             (sid,)).fetchall()
        types: list[str] = []
        for n in notes:
            if n["alert_type"] and n["alert_type"] not in types:
                types.append(n["alert_type"])
        last = notes[-1]
        jobs = [dict(r) for r in conn.execute("SELECT job_id, status, reason, latency_s FROM jobs"
                                              " WHERE superevent_id=? ORDER BY job_id", (sid,))]
        plans = []
        for p in conn.execute("SELECT plan_id, job_id, revision, final, withdrawn, document FROM plans"
                              " WHERE superevent_id=? ORDER BY seq", (sid,)):
            doc = _loads(p["document"])
            metrics = doc.get("metrics") or {}
            plans.append({
                "plan_id": p["plan_id"], "job_id": p["job_id"], "revision": p["revision"],
                "final": bool(p["final"]), "withdrawn": bool(p["withdrawn"]), "type": doc.get("type"),
                "coverage": metrics.get("coverage"), "expected_detections": metrics.get("expected_detections"),
                "published": bool(published.get(p["plan_id"])),
                "submission": submissions.get(p["plan_id"]),
            })
        ev = conn.execute("SELECT retracted FROM events WHERE superevent_id=?", (sid,)).fetchone()
        out.append({
            "superevent_id": sid, "last_received": last["received_at"], "alert_types": types,
            "notices": len(notes), "decision": last["decision"], "reason": last["reason"],
            "jobs": jobs, "plans": plans, "retracted": bool(ev["retracted"]) if ev else False,
        })
    return out


def attention(conn: sqlite3.Connection, now: datetime | None = None, outbox_max_age_s: float = 300.0,
              window_s: float = 86400.0) -> list[str]:
    """What an operator must look at, one line each ([] when all is well).

    Parameters
    ----------
    now : datetime, optional
    outbox_max_age_s : float
        An unpublished outbox message older than this (s) needs attention.
    window_s : float
        Failed jobs and offset jumps count when they happened this recently (s).
    """
    now = now or datetime.now(timezone.utc)
    lines = []
    for r in conn.execute("SELECT job_id, superevent_id, reason, finished_at, created_at FROM jobs"
                          " WHERE status='failed' ORDER BY job_id"):
        age = _age_s(r["finished_at"] or r["created_at"], now)
        if age is None or age <= window_s:
            lines.append(f"job {r['job_id']} of {r['superevent_id']} failed: {(r['reason'] or '-')[:200]}")
    for r in conn.execute("SELECT outbox_id, key, kind, created_at, attempts, last_error FROM outbox"
                          " WHERE published_at IS NULL ORDER BY outbox_id"):
        age = _age_s(r["created_at"], now)
        if age is not None and age > outbox_max_age_s:
            lines.append(f"outbox {r['kind']} {r['key']} unpublished for {age / 60:.1f} min after "
                         f"{r['attempts']} attempt(s): {(r['last_error'] or '-')[:200]}")
    for r in conn.execute("SELECT n.notice_id, n.origin, n.received_at FROM notices n"
                          " LEFT JOIN decisions d USING(notice_id) WHERE d.decision_id IS NULL ORDER BY n.notice_id"):
        lines.append(f"notice {r['notice_id']} from {r['origin']} ({r['received_at']}) has no decision")
    for inc in incidents(conn, "offset_jump"):
        age = _age_s(inc["created_at"], now)
        if age is None or age <= window_s:
            d = inc["detail"]
            lines.append(f"{d.get('skipped', '?')} message(s) of {d.get('topic', '?')}[{d.get('partition', '?')}] "
                         f"skipped at {inc['created_at']} (offsets {d.get('expected', '?')} -> {d.get('got', '?')}; "
                         f"{d.get('cause', '')})")
    return lines


def oldest_pending_submission(conn: sqlite3.Connection, now: datetime | None = None) -> dict[str, Any] | None:
    """The submission pending longest: ``{queue_name, target, body, superevent_id, age_s, attempts, answer}``,
    None when none (``queue_name``: the name base; ``body``: the stored request text, whose queues are named
    by :func:`~mushrooms.daemon.submission.names.row_queues`).

    A file without a ``submissions`` table has none.  A superseded or withdrawn row that only watches for
    a queue it sent without an answer (``progress.watch``: it is not waiting to be submitted) is not one.
    """
    now = now or datetime.now(timezone.utc)
    try:
        watching = " AND NOT (json_valid(progress) AND json_extract(progress, '$.watch') IS NOT NULL)" \
            if "progress" in {r[1] for r in conn.execute("PRAGMA table_info(submissions)")} else ""
        row = conn.execute(f"SELECT * FROM submissions WHERE state='pending'{watching} ORDER BY created_at"
                           " LIMIT 1").fetchone()
    except sqlite3.OperationalError as exc:
        if "no such table" in str(exc):
            return None
        raise
    if row is None:
        return None
    got = dict(zip(row.keys(), tuple(row))) if hasattr(row, "keys") else {}
    age = _age_s(got.get("created_at"), now)
    return {"queue_name": got.get("queue_name"), "target": got.get("target"), "body": got.get("body"),
            "superevent_id": got.get("superevent_id"),
            "age_s": max(0.0, age or 0.0), "attempts": got.get("attempts", 0),
            "answer": (got.get("answer") or "")[:200] or None}
