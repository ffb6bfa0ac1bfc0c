"""The state file's ``telescope_parts`` table: each configured telescope's part of a job (issue 53, phase 4).

With ``[scheduler] telescopes = ["ztf", ...]`` every job (one sky map of an
event) has one row per telescope after ZTF: ``exported`` (its files are in the
outbox folder ``folder``), ``not_observable`` (recorded, nothing exported) or
``failed`` (``detail`` says why); later ``superseded`` (a newer map's job
exported its parts) or ``withdrawn`` (the event was retracted).  ZTF's part is
the job's revisions (the ``plans`` table, the outbox, the submissions) as
without this table.  ``round`` is the job's n-th ZTF revision the part was
planned around and ``held`` which (its key): a later revision's part of the
same telescope replaces the row (the job keeps its latest part per telescope;
the earlier one's folder is marked ``SUPERSEDED``).  A ZTF-only configuration
never writes a row; a state file of an earlier version gets the (empty) table,
or the two columns, at its next open (:data:`~mushrooms.daemon.state.schema.UPGRADES`).
"""

from __future__ import annotations

from typing import Any

from .records import now_iso

__all__ = ["PARTS_TABLE", "ROUND_COLUMNS", "PART_STATES", "record_part", "parts_of_job", "event_parts", "mark_parts"]

PARTS_TABLE = """
CREATE TABLE IF NOT EXISTS telescope_parts (
    job_id        INTEGER NOT NULL,
    telescope     TEXT NOT NULL,
    superevent_id TEXT NOT NULL,
    queue         TEXT NOT NULL,
    state         TEXT NOT NULL,
    plan_id       TEXT,
    folder        TEXT,
    detail        TEXT,
    created_at    TEXT NOT NULL,
    updated_at    TEXT NOT NULL,
    round         INTEGER NOT NULL DEFAULT 1,
    held          TEXT,
    PRIMARY KEY (job_id, telescope)
);
CREATE INDEX IF NOT EXISTS telescope_parts_event ON telescope_parts(superevent_id, state);
"""

#: What a part can be.
PART_STATES = ("exported", "not_observable", "failed", "superseded", "withdrawn")

_COLUMNS = ("job_id, telescope, superevent_id, queue, state, plan_id, folder, detail, created_at, updated_at,"
            " round, held")
#: ``round``: the job's n-th ZTF revision the part was planned around; ``held``: which (its key).
ROUND_COLUMNS = (("telescope_parts", "round", "INTEGER NOT NULL DEFAULT 1"), ("telescope_parts", "held", "TEXT"))


def record_part(store: Any, job_id: int, telescope: str, superevent_id: str, queue: str, state: str,
                plan_id: str | None, folder: str | None, detail: str = "", round_: int = 1,
                held: str | None = None) -> bool:
    """Record a job's part; False when the job already has that telescope's part of the same round (kept as it is).

    A part of another round (planned around another ZTF revision: ``held``
    differs) is replaced: the job keeps one row per telescope, its latest.
    """
    now = now_iso()
    with store.transaction() as c:
        cur = c.execute(f"INSERT INTO telescope_parts({_COLUMNS}) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)"
                        " ON CONFLICT(job_id, telescope) DO UPDATE SET state=excluded.state, queue=excluded.queue,"
                        " plan_id=excluded.plan_id, folder=excluded.folder, detail=excluded.detail,"
                        " updated_at=excluded.updated_at, round=excluded.round, held=excluded.held"
                        " WHERE telescope_parts.held IS NOT excluded.held",
                        (int(job_id), telescope, superevent_id, queue, state, plan_id, folder, detail[:500], now, now,
                         int(round_), held))
        return cur.rowcount == 1


def parts_of_job(store: Any, job_id: int) -> dict[str, dict[str, Any]]:
    """The job's recorded parts by telescope."""
    rows = store.connection().execute(f"SELECT {_COLUMNS} FROM telescope_parts WHERE job_id=?", (int(job_id),))
    return {r["telescope"]: dict(r) for r in rows}


def event_parts(store: Any, superevent_id: str | None = None) -> list[dict[str, Any]]:
    """Every part (of one event), oldest job first; [] for a file without the table."""
    sql = f"SELECT {_COLUMNS} FROM telescope_parts"
    args: tuple[Any, ...] = ()
    if superevent_id is not None:
        sql, args = sql + " WHERE superevent_id=?", (superevent_id,)
    try:
        rows = store.connection().execute(sql + " ORDER BY job_id, telescope", args).fetchall()
    except Exception:  # an older file opened read-only (status): no parts
        return []
    return [dict(r) for r in rows]


def mark_parts(store: Any, superevent_id: str, state: str, before_job: int | None = None) -> list[dict[str, Any]]:
    """Set the event's live parts (``exported``, ``not_observable``) to ``state``; the rows changed.

    ``before_job``: only the parts of older jobs (superseded by that job's).
    """
    now = now_iso()
    where = "superevent_id=? AND state IN ('exported', 'not_observable', 'failed')"
    args: tuple[Any, ...] = (superevent_id,)
    if before_job is not None:
        where, args = where + " AND job_id<?", args + (int(before_job),)
    with store.transaction() as c:
        rows = [dict(r) for r in c.execute(f"SELECT {_COLUMNS} FROM telescope_parts WHERE {where}", args)]
        c.execute(f"UPDATE telescope_parts SET state=?, updated_at=? WHERE {where}", (state, now) + args)
    return rows


def part_line(row: dict[str, Any]) -> str:
    """One part in words: ``ls4 (target_list): exported mushrooms-... in <folder>`` (status, rehearse)."""
    from ...handlers.text import storable
    from ...report.site import site_words

    plan = f" {row['plan_id']}" if row.get("plan_id") and row.get("state") != "not_observable" else ""
    why = f": {storable(row['detail'], 160)}" if row.get("detail") else ""
    where = f" in {row['folder']}" if row.get("folder") and row.get("state") != "not_observable" else ""
    return (f"{row.get('telescope')} ({row.get('queue')}): {row.get('state')}{site_words(str(row.get('telescope')))}"
            f"{plan}{why}{where}")
