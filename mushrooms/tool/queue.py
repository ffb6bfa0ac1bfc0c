"""``mushrooms queue list|delete NAME``: what sits in ZTF's ToO queue (through Kowalski), and removing a queue.

``[submit] url`` (or ``--url``) is Kowalski's base URL; the token comes from
``$MUSHROOMS_SUBMIT_TOKEN`` or the systemd credential ``submit_token``; the
DELETE's ``user`` is ``[export] user``.  The daemon's own queues are named
``ToO_<subprogram>_<superevent>_<plan tag>_<k>`` (queue ``k`` of the set of
the plan whose id starts with the tag: :func:`~mushrooms.scheduler_core.plan.exports.queue_name_base`);
``list`` groups them by event and plan, in the order their windows open, and
shows each queue's validity window in UTC and its number of targets; other
queues are listed after them.  A server's error is one short line.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, Sequence

from .common import add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = "list ZTF's ToO queues or delete one (through Kowalski)"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms queue`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("queue", HELP)
    p.add_argument("action", choices=("list", "delete"))
    p.add_argument("name", nargs="?", metavar="NAME", help="the queue to delete")
    p.add_argument("--url", help="Kowalski's base URL (default [submit] url)")
    p.add_argument("--json", action="store_true", help="list: print the server's list as JSON")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms queue`` on its own."""
    return execute("queue", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """List or delete; 0 done, 1 refused or not reached, 2 bad input."""
    from ..daemon.credentials import load_submit_token
    from ..daemon.submission.remote import KowalskiQueue, Unreachable
    from ..handlers.secret_text import refuse_url_credentials
    from ..scheduler_core.errors import InputError
    from .config import ConfigError, load_config

    config = load_config(args.config)
    url = args.url or config.submit.url
    if not url:
        raise ConfigError("no Kowalski URL: give --url or set [submit] url")
    try:  # the token comes from the credential; a password in --url would be printed and logged
        refuse_url_credentials(url, "--url", "the token comes from MUSHROOMS_SUBMIT_TOKEN or the systemd "
                               "credential submit_token")
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    if args.action == "delete" and not args.name:
        raise InputError("queue delete needs the NAME of the queue")
    token, _ = load_submit_token()
    client = KowalskiQueue(url, token, config.submit.timeout_s)
    try:
        if args.action == "list":
            queues = client.queues()
            print(json.dumps(queues, indent=1) if args.json else render(queues))
            return 0
        answer = client.delete(args.name, config.export.user)
    except (Unreachable, RuntimeError) as exc:
        print(_line(f"mushrooms queue: {exc}"), file=sys.stderr)
        return 1
    if answer.ok and answer.problem is None:
        print(f"deleted {args.name}")
        return 0
    print(_line(f"mushrooms queue: delete {args.name} refused: {answer.status}: {answer.message()}"),
          file=sys.stderr)
    return 1


def _line(text: str, limit: int = 300) -> str:
    flat = " ".join(str(text).split())
    return flat if len(flat) <= limit else flat[:limit] + "..."


def _utc(mjd: Any) -> str:
    try:
        from datetime import datetime, timedelta, timezone

        t = datetime(1858, 11, 17, tzinfo=timezone.utc) + timedelta(days=float(mjd))
        return t.strftime("%Y-%m-%dT%H:%M:%SZ")
    except (TypeError, ValueError, OverflowError):
        return "?"


def _describe(q: dict[str, Any]) -> str:
    window = q.get("validity_window_mjd") or ["?", "?"]
    try:
        targets = q.get("queue", q.get("targets"))
        n: Any = len(json.loads(targets) if isinstance(targets, str) else targets or [])
    except (TypeError, ValueError):
        n = "?"
    start, end = (window + ["?", "?"])[:2] if isinstance(window, list) else ("?", "?")
    return f"{_line(q.get('queue_name'), 120)}  {_utc(start)} - {_utc(end)}  {n} targets"


def _opens(members: list[tuple[int, dict[str, Any]]]) -> float:
    """When the first queue of a plan's set opens (MJD; unknown: last)."""
    try:
        return min(float(q["validity_window_mjd"][0]) for _, q in members)
    except (KeyError, TypeError, ValueError, IndexError):
        return float("inf")


def render(queues: list[dict[str, Any]]) -> str:
    """The queue list grouped by event and plan (the daemon's names), then the other queues."""
    from ..scheduler_core.plan.exports import QUEUE_NAME  # the daemon's names, and those of the versions before

    groups: dict[tuple[str, str], list[tuple[int, dict[str, Any]]]] = {}
    other = []
    for q in queues:
        m = QUEUE_NAME.match(str(q.get("queue_name") or ""))
        if m:
            groups.setdefault((m["event"] or "sky map", m["tag"]), []).append((int(m["k"]), q))
        else:
            other.append(q)
    out = []
    for (event, tag), members in sorted(groups.items(), key=lambda kv: (kv[0][0], _opens(kv[1]), kv[0][1])):
        out.append(f"{event} plan {tag}: {len(members)} queue(s)")
        out.extend(f"  {_describe(q)}" for _, q in sorted(members, key=lambda kq: kq[0]))
    if other:
        out.append(f"other queues: {len(other)}")
        out.extend(f"  {_describe(q)}" for q in other)
    return "\n".join(out) if out else "no queue"


if __name__ == "__main__":
    sys.exit(main())
