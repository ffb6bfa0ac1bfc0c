"""The plan documents in the state file, read-only, for the summaries ``status`` and ``trigger`` print.

The service stores every revision it made, with its document, in the state
file's ``plans`` table (in order: ``seq``).  These helpers read them through
a read-only connection (:func:`mushrooms.daemon.state.views.connect_readonly`)
and never write.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

__all__ = ["last_seq", "documents_since", "current_document", "read_state"]


def _doc(text: str | None) -> dict[str, Any] | None:
    try:
        doc = json.loads(text or "")
    except ValueError:
        return None
    return doc if isinstance(doc, dict) else None


def last_seq(conn: sqlite3.Connection) -> int:
    """The newest revision's ``seq`` (0 without any)."""
    return int(conn.execute("SELECT COALESCE(MAX(seq), 0) FROM plans").fetchone()[0])


def documents_since(conn: sqlite3.Connection, seq: int) -> list[dict[str, Any]]:
    """The documents of the revisions stored after ``seq``, oldest first (withdrawn ones left out)."""
    rows = conn.execute("SELECT document FROM plans WHERE seq > ? AND withdrawn = 0 ORDER BY seq", (seq,))
    return [d for d in (_doc(r[0]) for r in rows) if d is not None]


def current_document(conn: sqlite3.Connection, superevent_id: str) -> dict[str, Any] | None:
    """The event's newest revision that is not withdrawn (the one in force), or None.

    ``final`` is the state's: a revision a ``plan_final`` verdict closed is
    final although its document, published before the verdict, says ``false``.
    """
    row = conn.execute("SELECT document, final FROM plans WHERE superevent_id = ? AND withdrawn = 0 "
                       "ORDER BY seq DESC LIMIT 1", (superevent_id,)).fetchone()
    doc = _doc(row[0]) if row else None
    if doc is not None and doc.get("type") == "plan" and row[1]:
        doc["final"] = True
    return doc


def read_state(path: Path, read: Any, default: Any) -> Any:
    """``read(conn)`` on a read-only connection to ``path``; ``default`` when there is no readable state file."""
    from ..daemon.state.views import connect_readonly

    if not Path(path).is_file():
        return default
    try:
        conn = connect_readonly(path)
    except sqlite3.Error:
        return default
    try:
        return read(conn)
    except sqlite3.Error:
        return default
    finally:
        conn.close()
