"""``mushrooms queue list|delete NAME``: what sits in ZTF's ToO queue (through Kowalski), and removing a queue.

``[submit] url`` (or ``--url``) is Kowalski's base URL; the token comes from
``$MUSHROOMS_SUBMIT_TOKEN`` or the systemd credential ``submit_token``; the
DELETE's ``user`` is ``[export] user``.  The daemon's own queues are named
``ToO_<subprogram>_<superevent>_r<n>``.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

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
    from ..daemon.remote import KowalskiQueue, Unreachable
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
            if args.json:
                print(json.dumps(queues, indent=1))
            for q in [] if args.json else queues:
                window = q.get("validity_window_mjd") or ["?", "?"]
                try:
                    n = len(json.loads(q["queue"]) if isinstance(q.get("queue"), str) else q.get("queue") or [])
                except ValueError:
                    n = "?"
                print(f"{q.get('queue_name')}\tMJD {window[0]} - {window[1]}\t{n} targets")
            return 0
        answer = client.delete(args.name, config.export.user)
    except (Unreachable, RuntimeError) as exc:
        print(f"mushrooms queue: {exc}", file=sys.stderr)
        return 1
    if answer.ok:
        print(f"deleted {args.name}")
        return 0
    print(f"mushrooms queue: delete {args.name} refused: {answer.status}: {answer.message()}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
