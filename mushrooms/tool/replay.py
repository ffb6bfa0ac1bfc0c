"""``mushrooms replay NOTICE_OR_DIR...``: archived notices through the daemon's own path (:mod:`mushrooms.daemon.intake.replay`)."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from .common import add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = "run archived notices through the daemon's path"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms replay`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("replay", HELP)
    p.add_argument("notices", nargs="+", metavar="NOTICE_OR_DIR")
    p.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
    p.add_argument("--out", metavar="DIR", default="replay-out", help="directory sink for plans and withdrawals")
    p.add_argument("--state", metavar="FILE", help="SQLite state file (default: a fresh one in --out)")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms replay`` on its own."""
    return execute("replay", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Replay the notices, print a line per notice and the summary; the report's exit status."""
    from .config import load_config
    from ..daemon.intake.replay import replay_notices
    from ..offline import configure_astropy_offline
    from .overrides import override_config

    from ..inputs import state_file_problem
    from ..scheduler_core.errors import InputError

    configure_astropy_offline()
    config = override_config(load_config(args.config), allow_mock=args.allow_mock)
    if args.state and (problem := state_file_problem(args.state)) is not None:
        raise InputError(problem)
    report = replay_notices(args.notices, args.out, config, state=args.state, on_outcome=print_outcome)
    print_summary(report)
    return report.status


def print_outcome(path, outcome) -> None:
    """One line per notice on stdout, as soon as it is handled (:func:`~mushrooms.daemon.intake.replay.format_line`)."""
    from ..daemon.intake.replay import format_line

    print(format_line(path.name, outcome), flush=True)


def print_summary(report, tool: str = "replay") -> None:
    """Where the outbox and the state are, and every input error, on stderr."""
    print(f"mushrooms {tool}: {len(report.results)} notice(s); outbox {report.out_dir.resolve()}; "
          f"state {report.state.resolve()}", file=sys.stderr)
    for line in report.errors:
        print(f"mushrooms {tool}: error: {line}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
