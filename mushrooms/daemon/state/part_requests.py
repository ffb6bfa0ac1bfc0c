"""The state file's ``part_requests`` table: telescope parts sent to SkyPortal (``[submit_parts]``, issue 53).

One row per part (job, telescope, round) of a telescope whose description's
queue is ``skyportal``, once :class:`~mushrooms.daemon.submission.parts_sender.PartSender`
adopted it.  ``round`` is the part's (``telescope_parts.round``: the job's n-th
ZTF revision it was planned around, docs/design/telescopes.md J9): a job's
round-2 part replaces its round-1 part in ``telescope_parts`` but gets its own
row here, so both requests are followed (round 2 sent, round 1 then DELETEd)::

    pending ─► sent ─► replaced   a newer map's (or round's) part of the telescope stands (the request DELETEd)
       │         └───► deleted    the event was retracted (the request DELETEd)
       ├─► rejected  SkyPortal refused the POST (3xx, 4xx): never retried
       ├─► failed    no allocation, no usable request file, the window ended first, a DELETE refused
       └─► skipped   dry run, or the part was superseded / withdrawn before it was sent

``tried`` is set, in its own transaction, before every POST: a row ``pending``
with ``tried = 1`` may have reached SkyPortal (a kill -9, the deadline, a 5xx)
and is looked up by its ``plan_name`` before it is POSTed again.  The token
is never here: ``body`` is the JSON body, ``answer`` the server's text with
the token blanked out.  A table added at open (schema version kept, as
``telescope_parts``); a file whose table is keyed by (job, telescope) alone
(main b00c596, this week) has it rebuilt with ``round`` at its next open
(:data:`ROUND_REBUILD`, one transaction), its rows round 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from .records import now_iso

__all__ = ["PART_REQUESTS_TABLE", "ROUND_REBUILD", "Rebuild", "REQUEST_STATES", "OPEN_STATES", "add_request",
           "requests", "update_request"]

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
    round         INTEGER NOT NULL DEFAULT 1,
    PRIMARY KEY (job_id, telescope, round)
);
CREATE INDEX IF NOT EXISTS part_requests_state ON part_requests(state);
"""

_OLD_COLUMNS = ("job_id, telescope, superevent_id, plan_id, plan_name, state, reason, body, remote_id, http_status,"
                " answer, attempts, tried, created_at, updated_at")


@dataclass(frozen=True)
class Rebuild:
    """A schema step: ``table`` lacking ``column`` is rebuilt by ``sql`` (statements split on ``;``)."""

    table: str
    column: str
    sql: str


#: main b00c596's table (primary key (job_id, telescope)) rebuilt with ``round``: its rows kept, round 1.
ROUND_REBUILD = Rebuild("part_requests", "round", PART_REQUESTS_TABLE.replace(
    "EXISTS part_requests (", "EXISTS part_requests_round (", 1).split("CREATE INDEX")[0]
    + f"INSERT INTO part_requests_round({_OLD_COLUMNS}, round) SELECT {_OLD_COLUMNS}, 1 FROM part_requests;"
    + "DROP TABLE part_requests;ALTER TABLE part_requests_round RENAME TO part_requests;"
    + "CREATE INDEX IF NOT EXISTS part_requests_state ON part_requests(state);")

#: What a request row can be.
REQUEST_STATES = ("pending", "sent", "replaced", "deleted", "rejected", "failed", "skipped")
#: The states the sender still acts on.
OPEN_STATES = ("pending", "sent")

_COLUMNS = ("job_id", "telescope", "superevent_id", "plan_id", "plan_name", "state", "reason", "body", "remote_id",
            "http_status", "answer", "attempts", "tried", "created_at", "updated_at", "round")


def add_request(store: Any, row: dict[str, Any]) -> bool:
    """Adopt a part (``job_id``, ``telescope``, ``round``, ...); False when it already has a row (kept as it is)."""
    now = now_iso()
    values = {"reason": "", "body": None, "remote_id": None, "http_status": None, "answer": None, "attempts": 0,
              "tried": 0, "created_at": now, "updated_at": now, "round": 1, **row}
    with store.transaction() as c:
        cur = c.execute(f"INSERT INTO part_requests({', '.join(_COLUMNS)}) VALUES ({', '.join('?' * len(_COLUMNS))})"
                        " ON CONFLICT DO NOTHING", tuple(values[k] for k in _COLUMNS))
        return cur.rowcount == 1


def requests(store: Any, states: tuple[str, ...] = OPEN_STATES) -> list[dict[str, Any]]:
    """The rows in ``states``, oldest job (and round) first."""
    marks = ",".join("?" * len(states))
    rows = store.connection().execute(f"SELECT {', '.join(_COLUMNS)} FROM part_requests WHERE state IN ({marks})"
                                      " ORDER BY job_id, round, telescope", states)
    return [dict(r) for r in rows]


def update_request(store: Any, row: Mapping[str, Any], **values: Any) -> None:
    """Set some columns of the row ``row`` names (its ``job_id``, ``telescope``, ``round``; ``updated_at`` too).

    One transaction.
    """
    bad = set(values) - set(_COLUMNS)
    if bad:
        raise KeyError(f"no part_requests column(s) {sorted(bad)}")
    values["updated_at"] = now_iso()
    sets = ", ".join(f"{k}=?" for k in values)
    with store.transaction() as c:
        c.execute(f"UPDATE part_requests SET {sets} WHERE job_id=? AND telescope=? AND round=?",
                  (*values.values(), int(row["job_id"]), row["telescope"], int(row.get("round") or 1)))
