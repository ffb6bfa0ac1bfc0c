"""``mushrooms trigger NOTICE.json|SKYMAP.fits|SUPEREVENT_ID``: hand work to the service, or do it here (:mod:`mushrooms.daemon.trigger`)."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from .common import add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = "hand a notice, sky map or superevent to the daemon"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms trigger`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("trigger", HELP)
    p.add_argument("target", metavar="NOTICE.json|SKYMAP.fits|SUPEREVENT_ID")
    p.add_argument("--state", metavar="FILE", help="SQLite state file (overrides config)")
    p.add_argument("--outbox", metavar="DIR", help="directory sink when no daemon runs")
    p.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
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
    to :func:`~mushrooms.daemon.trigger.run_trigger`.
    """
    from ..daemon.settings import resolve_paths
    from ..daemon.trigger import classify, run_trigger
    from ..offline import configure_astropy_offline
    from .overrides import effective_config

    configure_astropy_offline()
    kind, payload = classify(args.target)
    config = effective_config(args)
    return run_trigger(args.target, kind, payload, config, resolve_paths(config.daemon),
                       force=bool(getattr(args, "force", False)))


if __name__ == "__main__":
    sys.exit(main())
