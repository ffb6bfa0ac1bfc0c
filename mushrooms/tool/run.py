"""``mushrooms run``: the service, a GCN Kafka consumer (:mod:`mushrooms.daemon.service`)."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from .settings_flag import add_set_option
from .common import add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = "run the service (GCN Kafka consumer)"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms run`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("run", HELP)
    p.add_argument("--bootstrap", metavar="HOST:PORT", help="local plaintext broker, no credentials")
    p.add_argument("--outbox", metavar="DIR", help="directory sink (overrides config)")
    p.add_argument("--state", metavar="FILE", help="SQLite state file (overrides config)")
    p.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
    add_set_option(p)
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms run`` on its own."""
    return execute("run", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Run the service until SIGTERM; its exit status.

    The service gets plain objects: the configuration (file plus the
    command-line overrides, :func:`~.overrides.effective_config`, read again
    at every SIGHUP) and the runtime paths resolved from it.
    """
    from ..daemon.service import main as service_main
    from ..daemon.settings import resolve_paths
    from ..inputs import state_file_problem
    from ..scheduler_core.errors import InputError
    from .overrides import effective_config

    # a directory, FIFO or device as the state file: one line, exit 2, before the pid file or the trigger
    # directory is made beside it (the unit does not restart on 2)
    if (problem := state_file_problem(resolve_paths(effective_config(args).daemon).state)) is not None:
        raise InputError(problem)
    return service_main(lambda: effective_config(args))


if __name__ == "__main__":
    sys.exit(main())
