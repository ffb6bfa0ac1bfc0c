"""``mushrooms trigger NOTICE.json|SKYMAP.fits|SUPEREVENT_ID [--closed-until TIME]``: hand work to the service, or do it here (:mod:`mushrooms.daemon.intake.trigger`).

``SUPEREVENT --closed-until TIME``: the telescope is closed until TIME; the
event is re-planned from the reopening, what was executed counted as done
(``docs/design/executed.md`` L6).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Sequence

from .common import add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main", "PrintConsole", "print_summaries"]

HELP = "hand a notice, sky map or superevent to the daemon"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms trigger`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("trigger", HELP)
    p.add_argument("target", metavar="NOTICE.json|SKYMAP.fits|SUPEREVENT_ID")
    p.add_argument("--state", metavar="FILE", help="SQLite state file (overrides config)")
    p.add_argument("--outbox", metavar="DIR", help="directory sink when no daemon runs")
    p.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
    p.add_argument("--closed-until", metavar="TIME",
                   help="with SUPEREVENT_ID: the telescope is closed until TIME (ISO-8601 UTC); re-plan the event "
                        "from the reopening, what was executed counting as done ([loop], docs/design/executed.md)")
    p.add_argument("--force", action="store_true",
                   help="plan even when the policy would not (old, insignificant, duplicate, retracted); "
                        "logged with the policy's reason; needs no daemon running")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms trigger`` on its own."""
    return execute("trigger", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Hand the target to the running daemon, or plan it here; the exit status.

    Reads the target, loads the configuration (file plus the command-line
    overrides) and resolves the runtime paths, then hands the plain values
    to :func:`~mushrooms.daemon.intake.trigger_command.run_trigger`.
    """
    from ..daemon.settings import resolve_paths
    from ..daemon.intake.trigger import classify, closure_payload
    from ..daemon.intake.trigger_command import run_trigger
    from ..offline import configure_astropy_offline
    from ..scheduler_core.errors import InputError
    from .overrides import effective_config

    configure_astropy_offline()
    kind, payload = classify(args.target)
    closed_until = getattr(args, "closed_until", None)
    if closed_until is not None:
        from ..scheduler_core.plan.document import iso_utc
        from ..scheduler_core.times import parse_time

        if kind != "superevent":
            raise InputError(f"--closed-until takes a superevent id (like S250101ab), not a {kind} file")
        if getattr(args, "force", False):
            raise InputError("--closed-until re-plans a planned event; it does not combine with --force")
        kind, payload = "closure", closure_payload(payload.decode(), iso_utc(parse_time(closed_until,
                                                                                          "--closed-until")))
    config = effective_config(args, runnable=False)  # a running daemon uses its own sink
    paths = resolve_paths(config.daemon)
    from ..daemon.intake.trigger import daemon_pid
    from ..inputs import state_file_problem
    from .overrides import require_sink_broker

    if (problem := state_file_problem(paths.state)) is not None:  # before anything is created beside it
        raise InputError(problem)
    if kind in ("superevent", "closure") and not paths.state.exists():  # nothing stored to plan from: create nothing
        raise InputError(f"{paths.state}: no such state file: a superevent id is planned again from the notices "
                         "the service stored; give --state FILE (the service's), or a notice or sky map file")
    if daemon_pid(paths.pid_file) is None:  # planned here, published by this process's own sink
        require_sink_broker(config)
    from .state_plans import documents_since, last_seq, read_state

    before = read_state(paths.state, last_seq, 0)
    status = run_trigger(args.target, kind, payload, config, paths, force=bool(getattr(args, "force", False)),
                         console=PrintConsole())
    print_summaries(read_state(paths.state, lambda conn: documents_since(conn, before), []), config)
    return status


def print_summaries(docs: Sequence[dict], config: Any = None) -> None:
    """The text summary of the newest revision the trigger produced (its rows in the outbox's ``.txt``), with
    the queue names the service gives it (``config``'s ``[submit]`` and ``[export]``)."""
    from ..report.summary import summary_text

    if docs:
        names, words = ((), "")
        if config is not None:
            from ..daemon.submission.names import publish_queues

            names, words = publish_queues(config.submit, config.export)(docs[-1])
        print()
        print(summary_text(docs[-1], rows=False, queues=names, queue_note=words), end="", flush=True)


class PrintConsole:
    """``mushrooms trigger``'s console: the outcome on stdout, notes, warnings and errors on stderr."""

    prefix = "mushrooms trigger:"

    def result(self, text: str) -> None:
        print(f"{self.prefix} {text}", flush=True)

    def note(self, text: str) -> None:
        print(f"{self.prefix} {text}", file=sys.stderr, flush=True)

    def warning(self, text: str) -> None:
        print(f"{self.prefix} warning: {text}", file=sys.stderr, flush=True)

    def error(self, text: str) -> None:
        print(f"{self.prefix} error: {text}", file=sys.stderr, flush=True)


if __name__ == "__main__":
    sys.exit(main())
