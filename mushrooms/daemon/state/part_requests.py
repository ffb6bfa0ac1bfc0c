"""The state file's ``part_requests`` table: telescope parts sent to SkyPortal (``[submit_parts]``, issue 53).

One row per part (job, telescope) of a telescope whose description's queue is
``skyportal``, once :class:`~mushrooms.daemon.submission.parts_sender.PartSender`
adopted it::

    pending ─► sent ─► replaced   a newer map's part of the telescope stands (the request DELETEd)
       │         └───► deleted    the event was retracted (the request DELETEd)
       ├─► rejected  SkyPortal refused the POST (3xx, 4xx): never retried
       ├─► failed    no allocation, no usable request file, the window ended first, a DELETE refused
       └─► skipped   dry run, or the part was superseded / withdrawn before it was sent

``tried`` is set, in its own transaction, before every POST: a row ``pending``
with ``tried = 1`` may have reached SkyPortal (a kill -9, the deadline, a 5xx)
and is looked up by its ``plan_name`` before it is POSTed again.  The token
is never here: ``body`` is the JSON body, ``answer`` the server's text with
the token blanked out.  A table added at open (schema version kept, as
``telescope_parts``).
"""

from __future__ import annotations

from typing import Any

from .records import now_iso

__all__ = ["PART_REQUESTS_TABLE", "REQUEST_STATES", "OPEN_STATES", "add_request", "requests", "update_request"]

PART_REQUESTS_TABLE = """
CREATE TABLE IF NOT EXISTS part_requests (
    job_id        INTEGER NOT NULL,
    telescope     TEXT NOT NULL,
    superevent_id TEXT NOT NULL,
    plan_id       TEXT,
    plan_name     TEXT NOT NULL UNIQUE,
    state         TEXT NOT NULL,
    reason        TEXT,
    body          TEXT,
    remote_id     TEXT,
    http_status   INTEGER,
    answer        TEXT,
    attempts      INTEGER NOT NULL DEFAULT 0,
    tried         INTEGER NOT NULL DEFAULT 0,
    created_at    TEXT NOT NULL,
    updated_at    TEXT NOT NULL,
    PRIMARY KEY (job_id, telescope)
);
CREATE INDEX IF NOT EXISTS part_requests_state ON part_requests(state);
"""

#: What a request row can be.
REQUEST_STATES = ("pending", "sent", "replaced", "deleted", "rejected", "failed", "skipped")
#: The states the sender still acts on.
OPEN_STATES = ("pending", "sent")

_COLUMNS = ("job_id", "telescope", "superevent_id", "plan_id", "plan_name", "state", "reason", "body", "remote_id",
            "http_status", "answer", "attempts", "tried", "created_at", "updated_at")


def add_request(store: Any, row: dict[str, Any]) -> bool:
    """Adopt a part (``job_id``, ``telescope``, ...); False when it already has a row (kept as it is)."""
    now = now_iso()
    values = {"reason": "", "body": None, "remote_id": None, "http_status": None, "answer": None, "attempts": 0,
              "tried": 0, "created_at": now, "updated_at": now, **row}
    with store.transaction() as c:
        cur = c.execute(f"INSERT INTO part_requests({', '.join(_COLUMNS)}) VALUES ({', '.join('?' * len(_COLUMNS))})"
                        " ON CONFLICT DO NOTHING", tuple(values[k] for k in _COLUMNS))
        return cur.rowcount == 1


def requests(store: Any, states: tuple[str, ...] = OPEN_STATES) -> list[dict[str, Any]]:
    """The rows in ``states``, oldest job first."""
    marks = ",".join("?" * len(states))
    rows = store.connection().execute(f"SELECT {', '.join(_COLUMNS)} FROM part_requests WHERE state IN ({marks})"
                                      " ORDER BY job_id, telescope", states)
    return [dict(r) for r in rows]


def update_request(store: Any, job_id: int, telescope: str, **values: Any) -> None:
    """Set some columns of one row (``updated_at`` too), in one transaction."""
    bad = set(values) - set(_COLUMNS)
    if bad:
        raise KeyError(f"no part_requests column(s) {sorted(bad)}")
    values["updated_at"] = now_iso()
    sets = ", ".join(f"{k}=?" for k in values)
    with store.transaction() as c:
        c.execute(f"UPDATE part_requests SET {sets} WHERE job_id=? AND telescope=?",
                  (*values.values(), int(job_id), telescope))
