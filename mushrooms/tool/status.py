"""``mushrooms status``: what the service did recently, and whether it needs attention.

Reads the state file read-only (:mod:`mushrooms.daemon.state.views`: a
``mode=ro`` SQLite connection, safe while the daemon runs) and prints the
most recent superevents: the alert types seen, the decision on the newest
notice, each plan revision with its coverage and expected detections,
whether it was published or is pending, and its submission state when the
state file records submissions.  Then what needs attention: a failed job, an
outbox message unpublished for ``--outbox-minutes``, a notice stored
without a decision, messages the consumer skipped (offset jumps), a plan
submission pending longer than ``[submit] max_pending_s`` (the plan did
not reach the telescope), a broker or a warm-up plan the daemon last
recorded as failing (every job may then fail the same way).

Without ``--state`` the state file is the config's ``[daemon] state_path``.

Exit status: 0 all well, 1 something needs attention (also: the state file
stayed busy, locked by a writer, for ``--busy-timeout``), 2 bad input (no
such state file, not a state file, a state file of an older schema).
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import sys
from datetime import datetime, timezone
from typing import Any, Sequence

from .common import EXIT_INPUT, add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main", "EXIT_ATTENTION"]

HELP = "show recent events, plans and publication from the state file; exit 1 if something needs attention"

#: Exit status when something needs attention.
EXIT_ATTENTION = 1


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms status`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("status", HELP)
    p.add_argument("--state", metavar="FILE", help="SQLite state file (default: the config's [daemon] state_path)")
    p.add_argument("--json", action="store_true", help="one JSON document on stdout (for scripts)")
    p.add_argument("--limit", type=int, default=10, metavar="N", help="superevents shown, newest first (default 10)")
    p.add_argument("--outbox-minutes", type=float, default=5.0, metavar="M",
                   help="an outbox message unpublished this long needs attention (default 5)")
    p.add_argument("--window-hours", type=float, default=24.0, metavar="H",
                   help="failed jobs and skipped messages of the last H hours need attention (default 24)")
    p.add_argument("--busy-timeout", type=float, default=5.0, metavar="S",
                   help="wait this long for a busy (locked) state file (default 5)")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms status`` on its own."""
    return execute("status", parser().parse_args(args), run)


def _state_path(args: argparse.Namespace) -> Any:
    from pathlib import Path

    if args.state:
        return Path(args.state).expanduser()
    from ..daemon.settings import resolve_paths

    return resolve_paths(_config(args).daemon).state


def _no_state_file(path: Any, given: bool) -> str:
    """The one line for a state file that is not there: which file, and how to name the right one."""
    where = "" if given else " (the config's [daemon] state_path: no service has run with it here)"
    return (f"{path}: no such state file{where}; give --state FILE: the service's, e.g. "
            "/var/lib/mushrooms/mushrooms-state.sqlite under the shipped systemd unit, or "
            "mushrooms-demo/state.sqlite after mushrooms demo")


def _config(args: argparse.Namespace) -> Any:
    from .config import load_config

    return load_config(getattr(args, "config", None))


def _schema_problem(conn: sqlite3.Connection) -> str | None:
    """Why this program cannot read the file (an older or newer schema), None when it can."""
    from ..daemon.state.schema import SCHEMA_VERSION

    version = conn.execute("PRAGMA user_version").fetchone()[0]
    if version == SCHEMA_VERSION:
        return None
    if version < SCHEMA_VERSION:
        return (f"state file of schema {version}, this program reads schema {SCHEMA_VERSION}: start the daemon "
                "(mushrooms run) on it once to upgrade it, or use the mushrooms version that wrote it")
    return f"state file of schema {version}, newer than this program's {SCHEMA_VERSION}: use a newer mushrooms"


def _submission_attention(conn: sqlite3.Connection, max_pending_s: float) -> list[str]:
    from ..daemon.state.views import oldest_pending_submission
    from ..daemon.submission.names import pending_queue_names, queues_phrase

    oldest = oldest_pending_submission(conn)
    if oldest is None or oldest["age_s"] <= max_pending_s:
        return []
    return [f"submission of {oldest['superevent_id']} ({queues_phrase(pending_queue_names(oldest))}) pending for "
            f"{oldest['age_s'] / 60:.1f} min after {oldest['attempts']} attempt(s) (the plan did not reach the "
            f"telescope; [submit] max_pending_s = {max_pending_s:g} s): {oldest['answer'] or '-'}"]


#: The Kafka clients whose broker the daemon records, in words.
_BROKER_NAMES = {"consumer": "input", "sink": "outbound"}


def _broker_attention(brokers: dict[str, Any]) -> list[str]:
    """A line for each broker the daemon last recorded as unreachable."""
    return [f"the {_BROKER_NAMES.get(client, client)} Kafka broker is unreachable since {b['since']} (recorded by "
            f"the daemon at {b['recorded_at']}): {b['error'] or '-'}" for client, b in sorted(brokers.items())
            if not b["up"]]


def _warm_attention(warm: dict[str, Any] | None) -> list[str]:
    """A line when the daemon last recorded its warm-up plan as failing (not ready: every job may fail so)."""
    if not warm or not warm["failed"]:
        return []
    return [f"the warm-up plan failed since {warm['since']} (recorded by the daemon at {warm['recorded_at']}): "
            f"{warm['error'] or '-'}: every job may fail the same way and the service is not ready; fix it, "
            "then reload (SIGHUP) to plan it again"]


def _warm_line(warm: dict[str, Any] | None) -> list[str]:
    if not warm:
        return []
    return [f"warm-up plan: {'FAILED' if warm['failed'] else 'ok'} since {warm['since']}"
            + (f": {warm['error'] or '-'}" if warm["failed"] else "") + f" (recorded {warm['recorded_at']})"]


def _broker_lines(brokers: dict[str, Any]) -> list[str]:
    if not brokers:
        return ["input broker: not recorded yet (no daemon of this version has run on this state file)"]
    return [f"{_BROKER_NAMES.get(client, client)} broker ({client}): "
            + (f"up since {b['since']}" if b["up"] else f"UNREACHABLE since {b['since']}: {b['error'] or '-'}")
            + f" (recorded {b['recorded_at']})" for client, b in sorted(brokers.items())]


def collect(conn: sqlite3.Connection, limit: int, outbox_minutes: float, window_hours: float,
            config: Any = None) -> dict[str, Any]:
    """The status document (what ``--json`` prints); ``config`` names the queues of a plan not yet submitted."""
    from ..daemon.state.views import (attention, broker_reachability, incidents, outbox_backlog, recent_events,
                                      warm_up_plan)

    now = datetime.now(timezone.utc)
    pending, oldest, error = outbox_backlog(conn, now)
    jobs = {r[0]: r[1] for r in conn.execute("SELECT status, COUNT(*) FROM jobs GROUP BY status")}
    return {
        "now": now.isoformat(timespec="seconds"),
        "events": _with_current_plans(conn, recent_events(conn, limit), now, config),
        "jobs": jobs,
        "outbox": {"pending": pending, "oldest_age_s": oldest, "last_error": error},
        "offset_jumps": incidents(conn, "offset_jump", limit=limit),
        # what a job did other than its decision said (e.g. ``combined_map_unusable``), by event
        "event_incidents": [i for i in incidents(conn, limit=limit)
                            if i["kind"] != "offset_jump" and isinstance(i["detail"], dict)
                            and i["detail"].get("superevent_id")],
        "brokers": broker_reachability(conn),
        "warm_up_plan": warm_up_plan(conn),  # the throw-away plan of the warm-up (ops/warm_record.py)
        "attention": attention(conn, now, outbox_minutes * 60.0, window_hours * 3600.0),
    }


def _queues(conn: sqlite3.Connection, doc: dict[str, Any], config: Any) -> tuple[tuple[str, ...], str]:
    """The plan's ZTF queue names and what became of them: its submission row's, else (with ``config``) the
    names it would be submitted as."""
    from ..daemon.state.views import has_table
    from ..daemon.submission.names import publish_queues, row_queues

    row = None
    if has_table(conn, "submissions"):  # a file of an older release may lack the body
        body = "body" if "body" in {r[1] for r in conn.execute("PRAGMA table_info(submissions)")} else "NULL"
        row = conn.execute(f"SELECT target, state, {body}, queue_name FROM submissions WHERE plan_id = ?",
                           (doc.get("plan_id"),)).fetchone()
    if row is not None and (row[2] or row[3]):
        return row_queues(*row)
    if config is None:
        return (), ""
    return publish_queues(config.submit, config.export)(doc)


def _with_current_plans(conn: sqlite3.Connection, events: list[dict[str, Any]], now: datetime,
                        config: Any = None) -> list[dict[str, Any]]:
    """Each event with ``current``: its revision in force in words (``plan_id``, ``answer``), and the newest
    event's with its text ``summary`` too (the one-row-per-exposure table is in the outbox's ``.txt``)."""
    from ..report.summary import answer_line, summary_text
    from .state_plans import current_document

    for k, ev in enumerate(events):
        ev["parts"] = _parts(conn, ev["superevent_id"])
        doc = None if ev.get("retracted") else current_document(conn, ev["superevent_id"])
        if doc is None:
            continue
        ev["current"] = {"plan_id": doc.get("plan_id"), "answer": answer_line(doc)}
        if k == 0:
            names, words = _queues(conn, doc, config)
            ev["current"]["summary"] = summary_text(doc, now=now, rows=False, queues=names, queue_note=words)
    return events


def _parts(conn: sqlite3.Connection, superevent_id: str) -> list[dict[str, Any]]:
    """The event's other telescopes' parts (issue 53; ``telescope_parts``), newest job first; [] without any."""
    from ..daemon.state.views import has_table

    if not has_table(conn, "telescope_parts"):
        return []
    rounds = _round(conn, "telescope_parts")
    cur = conn.execute(f"SELECT job_id, telescope, queue, state, plan_id, folder, detail, {rounds} AS round FROM"
                       " telescope_parts WHERE superevent_id = ? ORDER BY job_id DESC, telescope", (superevent_id,))
    names = [c[0] for c in cur.description]
    parts = [dict(zip(names, r)) for r in cur.fetchall()]
    if parts and has_table(conn, "part_requests"):  # [submit_parts]: what became of each SkyPortal request
        sent = {(r[0], r[1], r[2]): {"state": r[3], "remote_id": r[4], "reason": r[5]} for r in conn.execute(
            f"SELECT job_id, telescope, {_round(conn, 'part_requests')}, state, remote_id, reason FROM part_requests"
            " WHERE superevent_id = ?", (superevent_id,))}
        for p in parts:  # the request of the part's round (J9: a job's round 2 replaced its round 1)
            if (p["job_id"], p["telescope"], p["round"]) in sent:
                p["request"] = sent[(p["job_id"], p["telescope"], p["round"])]
    return parts


def _round(conn: sqlite3.Connection, table: str) -> str:
    """``round``, or ``1`` for a file (read as it is) whose ``table`` has no round yet (every part round 1)."""
    return "round" if "round" in {r[1] for r in conn.execute(f"PRAGMA table_info({table})")} else "1"


def _request_words(part: dict[str, Any]) -> str:
    """``; SkyPortal request sent (id 12)``: the part's ``[submit_parts]`` row in words; empty without one."""
    from ..handlers.text import storable

    req = part.get("request")
    if not req:
        return ""
    ident = f" (id {storable(req['remote_id'], 40)})" if req.get("remote_id") else ""
    why = f": {storable(req['reason'], 160)}" if req.get("reason") and req.get("state") != "sent" else ""
    return f"; SkyPortal request {req.get('state')}{ident}{why}"


def _part_lines(parts: list[dict[str, Any]]) -> list[str]:
    """ZTF's part (the revisions) and each other telescope's part of the newest job, one line each."""
    from ..daemon.state.parts import part_line

    if not parts:
        return []
    newest = parts[0]["job_id"]
    return (["  telescope ztf (ztf_too): the revisions above"]
            + [f"  telescope {part_line(p)} (job {p['job_id']}){_request_words(p)}" for p in parts
               if p["job_id"] == newest])


def _num(x: Any, fmt: str = ".4f") -> str:
    return "-" if x is None else format(float(x), fmt)


def render(doc: dict[str, Any]) -> str:
    """The human-readable report."""
    out = [f"mushrooms status at {doc['now']}"]
    jobs = doc["jobs"]
    out.append("jobs: " + (", ".join(f"{n} {s}" for s, n in sorted(jobs.items())) or "none"))
    ob = doc["outbox"]
    out.append(f"outbox: {ob['pending']} pending" + (f", the oldest {ob['oldest_age_s']:.0f} s old"
                                                     if ob["oldest_age_s"] is not None else ""))
    out.extend(_broker_lines(doc.get("brokers") or {}))
    out.extend(_warm_line(doc.get("warm_up_plan")))
    out.append("")
    if not doc["events"]:
        out.append("no superevent heard of yet")
    for ev in doc["events"]:
        out.append(f"{ev['superevent_id']}  last notice {ev['last_received']}  ({ev['notices']} notice(s): "
                   f"{' '.join(ev['alert_types']) or '-'}){'  RETRACTED' if ev['retracted'] else ''}")
        out.append(f"  decision: {ev['decision'] or 'NONE'}: {ev['reason'] or '-'}")
        for inc in doc.get("event_incidents", []):
            if inc["detail"].get("superevent_id") == ev["superevent_id"]:
                out.append(f"  {inc['kind']} (job {inc['detail'].get('job_id', '-')}, {inc['created_at']}): "
                           f"{inc['detail'].get('reason', '-')}")
        for j in ev["jobs"]:
            if j["status"] not in ("done", "superseded"):
                out.append(f"  job {j['job_id']}: {j['status']}" + (f" ({j['reason']})" if j["reason"] else ""))
        for p in ev["plans"]:
            sub = p.get("submission")
            out.append(f"  r{p['revision']}{' final' if p['final'] else ''} {p['plan_id']}: "
                       f"{p['type'] or 'plan'}, coverage {_num(p['coverage'])}, expected detections "
                       f"{_num(p['expected_detections'])}, {'published' if p['published'] else 'PENDING'}"
                       + (", withdrawn" if p["withdrawn"] else "")
                       + (f", submission {sub.get('state') or '?'}" if sub else ""))
        out.extend(_part_lines(ev.get("parts") or []))
        current = ev.get("current")
        if current:
            out.append(f"  in force: {current['plan_id']}: {current['answer']}")
            if current.get("summary"):
                out.extend(f"    {line}" for line in current["summary"].rstrip("\n").splitlines())
    out.append("")
    if doc["attention"]:
        out.append(f"NEEDS ATTENTION ({len(doc['attention'])}):")
        out.extend(f"  - {line}" for line in doc["attention"])
    else:
        out.append("nothing needs attention")
    return "\n".join(out)


def run(args: argparse.Namespace) -> int:
    """Print the status; 1 when something needs attention."""
    from ..inputs import state_file_problem

    path = _state_path(args)
    problem = state_file_problem(path)  # a directory, FIFO or device is named for what it is
    if problem is not None or not path.is_file():
        print(f"mushrooms status: error: {problem or _no_state_file(path, bool(args.state))}", file=sys.stderr)
        return EXIT_INPUT
    from ..daemon.state.views import connect_readonly

    config = _config(args)
    max_pending_s = config.submit.max_pending_s
    try:
        conn = connect_readonly(path, timeout_s=max(0.0, args.busy_timeout))
        try:
            problem = _schema_problem(conn)
            if problem:
                print(f"mushrooms status: error: {path}: {problem}", file=sys.stderr)
                return EXIT_INPUT
            doc = collect(conn, args.limit, args.outbox_minutes, args.window_hours, config)
            doc["attention"] += (_broker_attention(doc["brokers"]) + _warm_attention(doc["warm_up_plan"])
                                 + _submission_attention(conn, max_pending_s))
        finally:
            conn.close()
    except sqlite3.OperationalError as exc:
        if "locked" in str(exc) or "busy" in str(exc):
            print(f"mushrooms status: {path}: the state file is busy (locked by a writer for over "
                  f"{args.busy_timeout:g} s); try again, or look at what holds it", file=sys.stderr)
            return EXIT_ATTENTION
        print(f"mushrooms status: error: {path}: not a readable mushrooms state file ({exc})", file=sys.stderr)
        return EXIT_INPUT
    except sqlite3.DatabaseError as exc:
        print(f"mushrooms status: error: {path}: not a readable mushrooms state file ({exc})", file=sys.stderr)
        return EXIT_INPUT
    print(json.dumps(doc, indent=1, default=str) if args.json else render(doc))
    return EXIT_ATTENTION if doc["attention"] else 0


if __name__ == "__main__":
    sys.exit(main())
