"""``mushrooms submit PLAN.json``: one plan to ZTF's queue (Kowalski) or SkyPortal, as the daemon sends it.

The target, URL and gates come from ``[submit]`` (``--target``/``--url``
override them), the program fields from ``[export]``, the token from
``$MUSHROOMS_SUBMIT_TOKEN`` or the systemd credential ``submit_token``.  The
request is built and its answer classified by the daemon's own code
(:func:`~mushrooms.daemon.submission.submitter.build_body`,
:func:`~mushrooms.daemon.submission.submitter.send_queue`); nothing is recorded in
the daemon's state.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

from .common import add_common_options, execute, read_json_object, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = "submit one plan document to ZTF's ToO queue (Kowalski) or SkyPortal"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms submit`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("submit", HELP)
    p.add_argument("plan", metavar="PLAN.json", help="a plan document (mushrooms plan -o, or the daemon's output)")
    p.add_argument("--target", choices=("kowalski", "skyportal"), help="default [submit] target")
    p.add_argument("--url", help="base URL of the target (default [submit] url)")
    p.add_argument("--queue-name", metavar="NAME",
                   help="name base of the queues (default the one rule of the service and `plan --queue`: "
                        "ToO_<subprogram>_<superevent>_<12 hex of the plan id>; the queues end _1, _2, ...)")
    p.add_argument("--dry-run", action="store_true", help="print the request (token redacted) and send nothing")
    p.add_argument("--force", action="store_true", help="submit even when a [submit] gate would not")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms submit`` on its own."""
    return execute("submit", parser().parse_args(args), run)


def read_plan(path: str) -> dict:
    """A plan document from a file, or :class:`InputError` with one line."""
    from ..scheduler_core.errors import InputError

    doc = read_json_object(path)
    if doc.get("type") != "plan":
        raise InputError(f"{path} is not a plan document (type {doc.get('type')!r})")
    return doc


def submit_config(args: argparse.Namespace):
    """The config with ``--target``/``--url`` applied (a bad URL is one line)."""
    import dataclasses

    from .config import ConfigError, load_config

    config = load_config(args.config)
    sub = config.submit
    target = args.target or (sub.target if sub.target != "none" else None)
    if target is None:
        raise ConfigError("no target: give --target kowalski|skyportal or set [submit] target")
    try:
        sub = dataclasses.replace(sub, target=target, url=args.url or sub.url)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    return dataclasses.replace(config, submit=sub)


def run(args: argparse.Namespace) -> int:
    """Submit (or with ``--dry-run`` print) one plan; 0 accepted, 1 refused or not reached, 2 bad input."""
    from ..daemon.submission.remote import make_client
    from ..daemon.submission.rules import name_of
    from ..daemon.submission.submitter import build_body, gate, send_queue
    from ..scheduler_core.errors import InputError

    doc = read_plan(args.plan)
    config = submit_config(args)
    why = gate(doc, config.submit)
    if why and not args.force:
        print(f"mushrooms submit: not submitted: {why} (--force submits anyway)", file=sys.stderr)
        return 1
    from ..scheduler_core.plan.exports import queue_name_base

    name = args.queue_name or queue_name_base(config.export.subprogram_name, str(doc["plan_id"]),
                                              (doc.get("event") or {}).get("superevent_id"))
    try:
        body = build_body(doc, config.submit, config.export, name)
    except ValueError as exc:
        raise InputError(f"{args.plan}: {exc}") from None
    parts = body if isinstance(body, list) else [body]  # the revision's queue set (or SkyPortal plans), in order
    if args.dry_run:
        client = make_client(config.submit.target, config.submit.url, None, config.submit.timeout_s)
        requests = [(client.put_request(q) if config.submit.target == "kowalski" else client.post_request(q))
                    .describe() for q in parts]
        print(json.dumps(requests if isinstance(body, list) else requests[0], indent=1))
        return 0
    from ..daemon.credentials import load_submit_token

    token, _ = load_submit_token()
    client = make_client(config.submit.target, config.submit.url, token, config.submit.timeout_s)
    for part in parts:
        one = name_of(part) if isinstance(body, list) else name
        verdict = send_queue(client, part, one)
        status = verdict.answer.status if verdict.answer else "no answer"
        text = verdict.reason or (verdict.answer.message() if verdict.answer else "")
        if verdict.state != "submitted":
            what = "refused" if verdict.state == "rejected" else "not accepted (try again)"
            print(f"mushrooms submit: {one} {what}: {status}: {text}"[:500], file=sys.stderr)
            return 1
        remote = f" id {verdict.remote_id}" if verdict.remote_id else ""
        print(f"submitted {one} to {config.submit.target} ({status}){remote}{': ' + text if text else ''}")
    return 0

if __name__ == "__main__":
    sys.exit(main())
