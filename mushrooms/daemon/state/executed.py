"""The state file's ``executed`` table: every exposure the loop read, once (``docs/design/executed.md`` L2).

One row per exposure, whatever source reported it and however often:
identity is E2 (same field and filter, starts less than 1 s apart), and of
two reports of one exposure the larger ``processed_fraction`` stays (a later
report has seen more of the pipeline).  So storing the same file twice
changes nothing (:func:`store_executed` counts it ``unchanged``), and an
exposure the depot first lists half reduced and later whole ends whole.

The table is created by the store's ``_UPGRADES`` (schema 5).  These
functions take a :class:`~mushrooms.daemon.state.store.Store` and use its transactions; the
records are :class:`~mushrooms.scheduler_core.executed.ExecutedExposure`
(imported only when called: opening a store imports no astropy).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Iterable

if TYPE_CHECKING:
    from ...scheduler_core.executed import ExecutedExposure

__all__ = ["EXECUTED_TABLE", "Stored", "store_executed", "executed_between", "count_executed"]

#: The table (and its indexes), one step of the store's ``_UPGRADES``.
EXECUTED_TABLE = """
CREATE TABLE IF NOT EXISTS executed (
    exposure_id        INTEGER PRIMARY KEY AUTOINCREMENT,
    field_id           INTEGER NOT NULL,
    filter             TEXT NOT NULL,
    start              TEXT NOT NULL,
    start_unix         REAL NOT NULL,
    exposure_s         REAL NOT NULL,
    processed_fraction REAL NOT NULL,
    status             TEXT NOT NULL,
    source             TEXT NOT NULL,
    read_at            TEXT NOT NULL,
    updated_at         TEXT
);
CREATE INDEX IF NOT EXISTS executed_exposure ON executed(field_id, filter, start_unix);
CREATE INDEX IF NOT EXISTS executed_start ON executed(start_unix);
"""


@dataclass(frozen=True)
class Stored:
    """What one :func:`store_executed` call did.

    Attributes
    ----------
    added : int
        Exposures not seen before.
    updated : int
        Exposures seen before, now reported with a larger processed fraction.
    unchanged : int
        Exposures seen before with at least this fraction (a re-read).
    """

    added: int
    updated: int
    unchanged: int

    @property
    def changed(self) -> bool:
        """Something new was stored."""
        return bool(self.added or self.updated)


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds")


def store_executed(store: Any, exposures: Iterable["ExecutedExposure"], source: str) -> Stored:
    """Keep exposures in the ``executed`` table, one row per exposure (E2), in one transaction.

    Parameters
    ----------
    store : Store
        The state store.
    exposures : iterable of ExecutedExposure
        What a source reported (any order, duplicates allowed).
    source : str
        Where they came from (``file:...``, ``depot:...``), kept with a new row.

    Returns
    -------
    Stored
        Counts of added, updated and unchanged exposures.
    """
    from ...scheduler_core.executed import SAME_START_S, to_record

    added = updated = unchanged = 0  # (L2)
    now = _now()
    with store.transaction() as c:
        for e in exposures:
            t = float(e.start.unix)
            row = c.execute(
                "SELECT exposure_id, processed_fraction FROM executed WHERE field_id=? AND filter=?"
                " AND start_unix>? AND start_unix<? ORDER BY ABS(start_unix-?) LIMIT 1",
                (e.field_id, e.filter, t - SAME_START_S, t + SAME_START_S, t)).fetchone()
            if row is None:
                rec = to_record(e)
                c.execute("INSERT INTO executed(field_id, filter, start, start_unix, exposure_s, processed_fraction,"
                          " status, source, read_at) VALUES (?,?,?,?,?,?,?,?,?)",
                          (e.field_id, e.filter, rec["start"], t, e.exposure_s, e.processed_fraction, e.status,
                           source[:500], now))
                added += 1
            elif e.processed_fraction > float(row[1]):
                c.execute("UPDATE executed SET processed_fraction=?, status=?, exposure_s=?, updated_at=?"
                          " WHERE exposure_id=?", (e.processed_fraction, e.status, e.exposure_s, now, row[0]))
                updated += 1
            else:
                unchanged += 1
    return Stored(added, updated, unchanged)


def executed_between(store: Any, start_unix: float | None = None,
                     end_unix: float | None = None) -> tuple["ExecutedExposure", ...]:
    """The stored exposures starting in ``[start_unix, end_unix]`` (Unix s; None: unbounded), in start order."""
    from astropy.time import Time

    from ...scheduler_core.executed import ExecutedExposure

    lo = float("-inf") if start_unix is None else float(start_unix)
    hi = float("inf") if end_unix is None else float(end_unix)
    rows = store.connection().execute(
        "SELECT field_id, filter, start, exposure_s, processed_fraction, status FROM executed"
        " WHERE start_unix>=? AND start_unix<=? ORDER BY start_unix, field_id, filter", (lo, hi)).fetchall()
    return tuple(ExecutedExposure(int(r[0]), str(r[1]), Time(str(r[2]).rstrip("Z"), scale="utc"), float(r[3]),
                                  float(r[4]), str(r[5])) for r in rows)


def count_executed(store: Any) -> int:
    """Rows of the ``executed`` table."""
    return int(store.connection().execute("SELECT COUNT(*) FROM executed").fetchone()[0])
