"""``mushrooms study``: the paper's experiment on a Dask cluster (:mod:`mushrooms.evaluation.study`)."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from ..evaluation.study_defaults import DEFAULT_SEED, DEFAULT_SOLVERS
from .common import add_common_options, execute, require_extra, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = ("the paper's experiment on a Dask cluster: simulate or take sky maps, "
        "plan, score, tables and figures (resumable)")


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms study`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("study", HELP)
    add_arguments(p)
    add_common_options(p)
    return p


def add_arguments(sp: argparse.ArgumentParser) -> None:
    """The ``mushrooms study`` options (on an argparse subparser)."""
    src = sp.add_mutually_exclusive_group()
    src.add_argument("--maps", metavar="DIR", help="plan the existing sky maps under DIR (no localisation)")
    src.add_argument("--events", metavar="EVENTS.xml.gz",
                     help="localise the coincidences of this events file (default: the packaged O3 BNS "
                          "population, 21 coincidences of 600 injections)")
    src.add_argument("--simulate", type=int, metavar="N",
                     help="simulate a new population of N injections (bayestar-inject, realize-coincs) and "
                          "localise its coincidences")
    sp.add_argument("--seed", type=int, default=DEFAULT_SEED, help="seed of --simulate (default %(default)s)")
    sp.add_argument("--intrinsic-samples", type=int, metavar="N",
                    help="with --simulate: N mass-spin points of bns_astro given to bayestar-inject "
                         "--distribution-samples instead of its preset's 10^4-cell horizon grid (~30 CPU-min)")
    sp.add_argument("--detections", type=int, metavar="N",
                    help="with --simulate: realise chunks of injections in order until they hold N coincidences, "
                         "and localise those N")
    sp.add_argument("--chunk", type=int, default=50, metavar="N",
                    help="with --simulate: injections per bayestar-realize-coincs task (default %(default)s)")
    sp.add_argument("--only-simulate", action="store_true",
                    help="with --simulate: stop after the simulation (print its events files)")
    sp.add_argument("--limit", type=int, metavar="N", help="only the first N coincidences / maps")
    sp.add_argument("--solvers", default=",".join(DEFAULT_SOLVERS),
                    help="comma list of greedy,slots,blocks,hybrid,milp,gwemopt,gwemopt-repaired; ours as "
                         "published under the config's objective, or forced with -coverage / -detection "
                         "(hybrid-coverage) (default %(default)s)")
    sp.add_argument("--injections", type=int, default=10000, metavar="N", help="kilonova injections per map")
    sp.add_argument("--start", metavar="ISO_UTC", help="one start time for every map (default: each map's event time)")
    where = sp.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=2, metavar="N",
                       help="local cluster of N single-threaded worker processes (default %(default)s)")
    where.add_argument("--scheduler", metavar="ADDRESS", help="use a running Dask scheduler (tcp://host:8786)")
    sp.add_argument("--out", metavar="DIR", default="study", help="results, tables, figures (default %(default)s)")
    sp.add_argument("--cache", metavar="DIR",
                    help="simulated populations and localised maps (default: $MUSHROOMS_CACHE_DIR/study, "
                         "else ~/.cache/mushrooms/study)")
    sp.add_argument("--no-figures", action="store_true", help="tables only")
    sp.add_argument("--dashboard", action="store_true", help="serve the local cluster's dashboard on a free port")


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms study`` on its own."""
    return execute("study", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Run the study; the exit status."""
    from .bench import require_gwemopt

    if not getattr(args, "maps", None):  # simulate and/or localise (bayestar-*): lalsuite, igwn-ligolw
        require_extra("simulate")
    require_extra("study")  # the task graph on Dask distributed
    require_gwemopt(args)
    from ..evaluation.study import main as study_main

    return study_main(args)


if __name__ == "__main__":
    sys.exit(main())
