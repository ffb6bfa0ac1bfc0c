"""Command line: ``mushrooms run | plan | check | replay | trigger | bench``.

Bad input is answered by one line on stderr and exit status 2; ``--debug``
shows tracebacks.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from typing import Callable, Sequence

from . import __version__

#: ``--solver`` names (scheduler_core.config.SOLVER_NAMES, kept here so ``--help`` imports nothing heavy;
#: tests/test_cli.py keeps the two equal).
SOLVER_CHOICES = ["greedy", "slots", "blocks", "hybrid", "milp"]

__all__ = ["main", "build_parser"]

EXIT_INPUT = 2
EXIT_INTERNAL = 70

# subcommand -> "module:function"; each function takes the parsed args and returns an exit code
COMMANDS = {
    "demo": "mushrooms.commands:demo_main",
    "plan": "mushrooms.commands:plan_main",
    "check": "mushrooms.commands:check_main",
    "replay": "mushrooms.daemon.replay:main",
    "run": "mushrooms.daemon.service:main",
    "trigger": "mushrooms.daemon.trigger:main",
    "bench": "mushrooms.evaluation.bench:main",
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
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    def common(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--config", metavar="FILE",
                        help="config file; default $MUSHROOMS_CONFIG, else ./config.toml, else embedded defaults")
        # the global options are accepted after the subcommand too (SUPPRESS keeps the global value)
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
        sp.add_argument("--log-level", default=argparse.SUPPRESS, help=argparse.SUPPRESS)

    sp = sub.add_parser("demo", help="plan the bundled mock BNS notice end to end (no credentials, no network)")
    sp.add_argument("--out", metavar="DIR", default="mushrooms-demo", help="where the plan, its picture and the state go")
    sp.add_argument("--solver", choices=SOLVER_CHOICES,
                    help="scheduler: greedy | slots | blocks (the paper's block MILP; milp = blocks) | hybrid "
                         "(default from config: hybrid)")
    common(sp)

    sp = sub.add_parser("plan", help="plan a ZTF night from a sky map")
    sp.add_argument("skymap", nargs="?", metavar="SKYMAP",
                    help="sky map FITS (multi-order or flat HEALPix); default: the bundled demo map")
    sp.add_argument("--start", metavar="TIME",
                    help="horizon start: ISO-8601 (Z or +hh:mm offset; no offset means UTC) or MJD "
                         "(default: the sky map's event time)")
    sp.add_argument("--solver", choices=SOLVER_CHOICES,
                    help="scheduler: greedy | slots | blocks (the paper's block MILP; milp = blocks) | hybrid "
                         "(default from config: hybrid)")
    sp.add_argument("-o", "--output", metavar="FILE", default="plan.json", help="plan document to write (default plan.json)")
    sp.add_argument("--deadline", metavar="SECONDS", type=float,
                    help="write the best plan found by then: the greedy plan at once, the optimised one if it is "
                         "ready and covers more (default: wait for the solver)")
    sp.add_argument("--queue", metavar="FILE", help="also write ZTF's ToO trigger queue (program fields from [export])")
    sp.add_argument("--skyportal", metavar="FILE",
                    help="also write the body of SkyPortal's POST /api/observation_plan/manual")
    sp.add_argument("--plot", metavar="FILE", help="also draw the plan on the sky map (PNG)")
    common(sp)

    sp = sub.add_parser("check", help="check a plan document against a sky map")
    sp.add_argument("plan", metavar="PLAN_JSON")
    sp.add_argument("skymap", metavar="SKYMAP")
    common(sp)

    sp = sub.add_parser("replay", help="run archived notices through the daemon's path")
    sp.add_argument("notices", nargs="+", metavar="NOTICE_OR_DIR")
    sp.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
    sp.add_argument("--out", metavar="DIR", default="replay-out", help="directory sink for plans and withdrawals")
    sp.add_argument("--state", metavar="FILE", help="SQLite state file (default: a fresh one in --out)")
    common(sp)

    sp = sub.add_parser("run", help="run the service (GCN Kafka consumer)")
    sp.add_argument("--bootstrap", metavar="HOST:PORT", help="local plaintext broker, no credentials")
    sp.add_argument("--outbox", metavar="DIR", help="directory sink (overrides config)")
    sp.add_argument("--state", metavar="FILE", help="SQLite state file (overrides config)")
    sp.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
    common(sp)

    sp = sub.add_parser("trigger", help="hand a notice, sky map or superevent to the daemon")
    sp.add_argument("target", metavar="NOTICE.json|SKYMAP.fits|SUPEREVENT_ID")
    sp.add_argument("--state", metavar="FILE", help="SQLite state file (overrides config)")
    sp.add_argument("--outbox", metavar="DIR", help="directory sink when no daemon runs")
    sp.add_argument("--allow-mock", action="store_true", help="accept mock (MS) and test (TS) events")
    sp.add_argument("--force", action="store_true",
                    help="plan even when the policy would not (old, insignificant, duplicate, retracted); "
                         "logged with the policy's reason; needs no daemon running")
    common(sp)

    sp = sub.add_parser("bench", help="benchmark schedulers over a directory of sky maps")
    sp.add_argument("skymap_dir", metavar="SKYMAP_DIR")
    g = sp.add_mutually_exclusive_group()
    g.add_argument("--start-from-event", action="store_true", help="start each plan at its map's event time (default)")
    g.add_argument("--start", metavar="ISO_UTC", help="one start time for every map")
    sp.add_argument("--solvers", default="greedy,slots,blocks,hybrid",
                    help="comma list of greedy,slots,blocks,hybrid,milp,gwemopt,gwemopt-repaired")
    sp.add_argument("--jobs", type=int, default=1, metavar="N", help="maps in parallel processes")
    sp.add_argument("--injections", type=int, default=10000, metavar="N", help="kilonova injections per map")
    sp.add_argument("--plots", metavar="DIR", help="write the summary figures here")
    sp.add_argument("-o", "--output", metavar="FILE", default="results.csv")
    common(sp)
    return p


def quiet_time_warnings() -> None:
    """No ERFA/IERS chatter: far-off times are reported once, in one line, by the command."""
    import warnings

    warnings.filterwarnings("ignore", message=r".*dubious year.*")
    warnings.filterwarnings("ignore", message=r".*polar motions for times.*")
    warnings.filterwarnings("ignore", message=r".*outside of range covered by IERS table.*")
    warnings.filterwarnings("ignore", message=r".*IERS.*")
    try:
        from erfa import ErfaWarning
    except ImportError:  # pragma: no cover - astropy always brings pyerfa
        return
    warnings.filterwarnings("ignore", category=ErfaWarning)


def _resolve(spec: str) -> Callable[[argparse.Namespace], int]:
    module, func = spec.split(":")
    return getattr(importlib.import_module(module), func)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mushrooms`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return EXIT_INPUT
    level = logging.DEBUG if args.debug else getattr(logging, str(args.log_level).upper(), None)
    if not isinstance(level, int):
        print(f"mushrooms {args.command}: error: --log-level {args.log_level!r}: expected DEBUG, INFO, WARNING "
              "or ERROR", file=sys.stderr)
        return EXIT_INPUT
    logging.basicConfig(
        level=level,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    quiet_time_warnings()
    from .config import ConfigError, resolve_config_path
    from .scheduler_core.errors import InputError

    try:
        if hasattr(args, "config"):
            given = args.config
            path, why = resolve_config_path(given)
            args.config, args.config_explicit = (str(path) if path else None), bool(given)
            logging.getLogger("mushrooms.config").info("config: %s (%s)", path or "embedded defaults", why)
        return int(_resolve(COMMANDS[args.command])(args) or 0)
    except (InputError, ConfigError) as exc:
        print(f"mushrooms {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print(f"mushrooms {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal fault: still one line unless --debug
        if args.debug:
            raise
        print(f"mushrooms {args.command}: internal error: {type(exc).__name__}: {exc} (rerun with --debug)",
              file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
