"""Command line: ``mushrooms demo | plan | check | replay | run | rehearse | trigger | status | bench | study | submit
| queue | preflight | telescopes``.

A thin dispatcher: each subcommand is a module of :mod:`mushrooms.tool`
with its parser beside its implementation; :data:`TOOLS` is the registry.
Bad input is answered by one line on stderr and exit status 2; ``--debug``
shows tracebacks.
"""

from __future__ import annotations

import argparse
import sys
from types import ModuleType
from typing import Sequence

from . import __version__
from .tool import bench, check, demo, plan, queue, rehearse, replay, run, status, study, submit, trigger
from .tool import preflight
from .tool import telescopes
from .tool.common import EXIT_INPUT, SOLVER_CHOICES, execute

__all__ = ["main", "build_parser", "TOOLS", "SOLVER_CHOICES"]

#: subcommand -> tool module (``HELP``, ``parser(p)``, ``run(args)``), in ``--help`` order.
TOOLS: dict[str, ModuleType] = {
    "demo": demo, "plan": plan, "check": check, "replay": replay, "run": run, "rehearse": rehearse, "trigger": trigger,
    "status": status,
    "bench": bench, "study": study, "submit": submit, "queue": queue,
    "preflight": preflight,
    "telescopes": telescopes,
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    p = argparse.ArgumentParser(
        prog="mushrooms",
        description="Turn gravitational-wave alerts into ZTF follow-up plans (MUSHROOMS).",
    )
    p.add_argument("--version", action="version", version=f"mushrooms {__version__}")
    p.add_argument("--debug", action="store_true", help="show tracebacks and debug logs")
    p.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING (default INFO)")
    p.add_argument("--config", dest="global_config", metavar="FILE",
                   help="config file, before or after the command (after it wins)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name, tool in TOOLS.items():
        tool.parser(sub.add_parser(name, help=tool.HELP, description=tool.HELP))
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mushrooms`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return EXIT_INPUT
    if getattr(args, "config", None) is None and args.global_config is not None and hasattr(args, "config"):
        args.config = args.global_config  # `mushrooms --config FILE plan ...`, like --debug
    return execute(args.command, args, TOOLS[args.command].run)


if __name__ == "__main__":
    sys.exit(main())
