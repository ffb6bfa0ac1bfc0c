"""The state file's tables and how an older file is brought up to date (:data:`UPGRADES`).

:class:`~mushrooms.daemon.state.store.Store` creates :data:`SCHEMA` in a new file and applies
:func:`missing_steps` at every open; the tables are described in
:mod:`~mushrooms.daemon.state.store`'s docstring.  The ``executed`` table's statement is its
module's (:mod:`~mushrooms.daemon.state.executed`).
"""

from __future__ import annotations

import sqlite3

from .executed import EXECUTED_TABLE
from .part_requests import PART_REQUESTS_TABLE, ROUND_REBUILD, Rebuild
from .parts import PARTS_TABLE, ROUND_COLUMNS

__all__ = ["SCHEMA_VERSION", "SCHEMA", "UPGRADES", "missing_steps"]

SCHEMA_VERSION = 6

#: Plans submitted to ZTF's queue (Kowalski or SkyPortal): one row per plan id (:mod:`~mushrooms.daemon.submission.submitter`).
SUBMISSIONS = """
CREATE TABLE IF NOT EXISTS submissions (
    plan_id       TEXT PRIMARY KEY,
    superevent_id TEXT NOT NULL,
    target        TEXT NOT NULL,
    revision      INTEGER,
    queue_name    TEXT UNIQUE,
    state         TEXT NOT NULL,
    reason        TEXT,
    body          TEXT,
    remote_id     TEXT,
    http_status   INTEGER,
    answer        TEXT,
    attempts      INTEGER NOT NULL DEFAULT 0,
    created_at    TEXT NOT NULL,
    attempted_at  TEXT,
    submitted_at  TEXT,
    finished_at   TEXT,
    progress      TEXT
);
CREATE INDEX IF NOT EXISTS submissions_event ON submissions(superevent_id, state);
"""

SCHEMA = """
CREATE TABLE IF NOT EXISTS notices (
    notice_id     INTEGER PRIMARY KEY AUTOINCREMENT,
    received_at   TEXT NOT NULL,
    origin        TEXT NOT NULL,
    sha256        TEXT NOT NULL,
    size          INTEGER NOT NULL,
    superevent_id TEXT,
    alert_type    TEXT,
    time_created  TEXT,
    raw           BLOB
);
CREATE INDEX IF NOT EXISTS notices_sha ON notices(sha256);
CREATE TABLE IF NOT EXISTS decisions (
    decision_id   INTEGER PRIMARY KEY AUTOINCREMENT,
    notice_id     INTEGER NOT NULL REFERENCES notices(notice_id),
    superevent_id TEXT,
    alert_type    TEXT,
    decision      TEXT NOT NULL,
    reason        TEXT NOT NULL,
    job_id        INTEGER,
    created_at    TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS events (
    superevent_id TEXT PRIMARY KEY,
    skymap_sha256 TEXT,
    retracted     INTEGER NOT NULL DEFAULT 0,
    updated_at    TEXT NOT NULL,
    localization  TEXT,
    latest_created TEXT
);
CREATE TABLE IF NOT EXISTS jobs (
    job_id        INTEGER PRIMARY KEY AUTOINCREMENT,
    notice_id     INTEGER NOT NULL REFERENCES notices(notice_id),
    superevent_id TEXT NOT NULL,
    alert_type    TEXT NOT NULL,
    time_created  TEXT,
    skymap_sha256 TEXT NOT NULL,
    decision      TEXT NOT NULL,
    start         TEXT NOT NULL,
    supersedes    TEXT,
    received_wall REAL NOT NULL,
    status        TEXT NOT NULL,
    attempts      INTEGER NOT NULL DEFAULT 0,
    plan_id       TEXT,
    coverage      REAL,
    latency_s     REAL,
    reason        TEXT,
    created_at    TEXT NOT NULL,
    finished_at   TEXT
);
CREATE INDEX IF NOT EXISTS jobs_status ON jobs(status);
CREATE INDEX IF NOT EXISTS jobs_event ON jobs(superevent_id);
CREATE TABLE IF NOT EXISTS plans (
    plan_id       TEXT PRIMARY KEY,
    superevent_id TEXT,
    job_id        INTEGER,
    created_at    TEXT NOT NULL,
    seq           INTEGER NOT NULL,
    withdrawn     INTEGER NOT NULL DEFAULT 0,
    document      TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS plans_event ON plans(superevent_id);
CREATE TABLE IF NOT EXISTS outbox (
    outbox_id     INTEGER PRIMARY KEY AUTOINCREMENT,
    key           TEXT NOT NULL,
    kind          TEXT NOT NULL,
    body          TEXT NOT NULL,
    created_at    TEXT NOT NULL,
    published_at  TEXT,
    attempts      INTEGER NOT NULL DEFAULT 0,
    last_error    TEXT
);
CREATE INDEX IF NOT EXISTS outbox_pending ON outbox(published_at);
""" + SUBMISSIONS

#: How older state files are brought up to date: one list, in the order the schema grew.  Each step
#: is a table created when missing, a column (table, name, declaration) added when missing, or a table
#: of an earlier form rebuilt (:class:`~.part_requests.Rebuild`, when it lacks a column of its key); every
#: open applies what a file lacks, whatever its ``user_version`` says (a file of any earlier release,
#: or one whose version and tables disagree, ends with the same tables).  ``user_version`` is then
#: raised to :data:`SCHEMA_VERSION`; a file with a newer one is refused.  A new file gets
#: :data:`SCHEMA` and then the same steps.
UPGRADES: tuple[tuple[int, str | tuple[str, str, str] | Rebuild], ...] = (
    (2, ("plans", "revision", "INTEGER NOT NULL DEFAULT 1")),  # a job's revisions (anytime plans)
    (2, ("plans", "final", "INTEGER NOT NULL DEFAULT 1")),
    (2, ("events", "localization", "TEXT")),  # gw | combined: which map was planned
    # things an operator must hear of that are not notices, e.g. the consumer's offset jumps
    # (:meth:`Store.record_incident`, ``mushrooms status``); an older program ignores the table
    (3, "CREATE TABLE IF NOT EXISTS incidents (incident_id INTEGER PRIMARY KEY AUTOINCREMENT,"
        " kind TEXT NOT NULL, detail TEXT NOT NULL, created_at TEXT NOT NULL)"),
    (3, SUBMISSIONS),  # plans submitted to ZTF's queue (:mod:`~mushrooms.daemon.submission.submitter`)
    (4, ("events", "latest_created", "TEXT")),  # creation order of notices (an older notice arriving late is stale)
    (5, EXECUTED_TABLE),  # exposures the telescope took ([loop], :mod:`~mushrooms.daemon.state.executed`)
    # which queues of a revision's queue set were accepted / removed (:mod:`~mushrooms.daemon.submission.submitter`)
    (6, ("submissions", "progress", "TEXT")),
    # each configured telescope's part of a job after ZTF's (issue 53; :mod:`~mushrooms.daemon.state.parts`)
    (6, PARTS_TABLE),  # version kept: a table only, which an older program ignores (and reads the file)
    # the parts sent to SkyPortal ([submit_parts]; :mod:`~mushrooms.daemon.state.part_requests`), version kept likewise
    (6, PART_REQUESTS_TABLE),
    # a part's round (the job's ZTF revision it was planned around) and which revision (its key); issue 53 J9
    (6, ROUND_COLUMNS[0]), (6, ROUND_COLUMNS[1]),  # columns with defaults: an older program's rows still insert
    # a request per part round (job, telescope, round): main b00c596's table, keyed by (job, telescope), rebuilt
    (6, ROUND_REBUILD),
)


def _tables(conn: sqlite3.Connection) -> set[str]:
    return {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}


def missing_steps(conn: sqlite3.Connection) -> list[str]:
    """The statements of the :data:`UPGRADES` steps the file has not had."""
    tables = _tables(conn)
    out: list[str] = []
    for _, step in UPGRADES:
        if isinstance(step, str):
            names = [w.split("(")[0] for w in step.split("CREATE TABLE IF NOT EXISTS ")[1:]]
            if not set(n.strip() for n in names) <= tables:
                out.append(step)
            continue
        if isinstance(step, Rebuild):  # a table of an earlier form (its key changed): rebuilt, rows kept
            have = {r[1] for r in conn.execute(f"PRAGMA table_info({step.table})")} if step.table in tables else None
            if have is not None and step.column not in have:
                out.append(step.sql)
            continue
        table, column, decl = step
        if table not in tables:
            continue  # created by an earlier step of this list, with its column already
        if column not in {r[1] for r in conn.execute(f"PRAGMA table_info({table})")}:
            out.append(f"ALTER TABLE {table} ADD COLUMN {column} {decl}")
    return out
