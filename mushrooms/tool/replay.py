"""``mushrooms replay NOTICE_OR_DIR...``: archived notices through the daemon's own path (:mod:`mushrooms.daemon.replay`)."""

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
    """Replay the notices; the exit status of :func:`~mushrooms.daemon.replay.replay_notices`."""
    from .config import load_config
    from ..daemon.replay import replay_notices
    from ..offline import configure_astropy_offline
    from .overrides import override_config

    configure_astropy_offline()
    config = override_config(load_config(args.config), allow_mock=args.allow_mock)
    return replay_notices(args.notices, args.out, config, state=args.state)


if __name__ == "__main__":
    sys.exit(main())
