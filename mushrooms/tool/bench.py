"""``mushrooms bench SKYMAP_DIR``: schedule quality and kilonova detection efficiency (:mod:`mushrooms.evaluation.bench`)."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from .common import MissingExtra, add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main", "require_gwemopt"]

#: Rows that run the real gwemopt (the ``gwemopt`` extra, or its cache).
GWEMOPT_ROWS = ("gwemopt", "gwemopt-repaired")

HELP = "benchmark schedulers over a directory of sky maps"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms bench`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("bench", HELP)
    p.add_argument("skymap_dir", metavar="SKYMAP_DIR")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--start-from-event", action="store_true", help="start each plan at its map's event time (default)")
    g.add_argument("--start", metavar="ISO_UTC", help="one start time for every map")
    p.add_argument("--solvers", default="greedy,slots,blocks,hybrid",
                   help="comma list of greedy,slots,blocks,hybrid,milp,gwemopt,gwemopt-repaired; ours as "
                        "make_plan publishes them under the config (objective included), or with the "
                        "objective forced by -coverage / -detection (hybrid-coverage)")
    p.add_argument("--jobs", type=int, default=1, metavar="N", help="maps in parallel processes")
    p.add_argument("--injections", type=int, default=10000, metavar="N", help="kilonova injections per map")
    p.add_argument("--plots", metavar="DIR", help="write the summary figures here")
    p.add_argument("-o", "--output", metavar="FILE", default="results.csv")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms bench`` on its own."""
    return execute("bench", parser().parse_args(args), run)


def require_gwemopt(args: argparse.Namespace) -> None:
    """:class:`MissingExtra` when ``--solvers`` asks for gwemopt rows that nothing can produce.

    A gwemopt row needs gwemopt's interpreter (this one with the ``gwemopt``
    extra, or ``$MUSHROOMS_GWEMOPT_PYTHON`` / ``[bench] gwemopt_python``) or
    a cache of its schedules (``[bench] gwemopt_cache_dir``, whose misses are
    rows saying ``unavailable``).
    """
    asked = [s.strip() for s in str(getattr(args, "solvers", "")).split(",") if s.strip() in GWEMOPT_ROWS]
    if not asked:
        return
    from ..evaluation.bench import _load_settings
    from ..evaluation.gwemopt_baseline import ENV_PYTHON, gwemopt_python

    settings = _load_settings(args)
    if gwemopt_python(settings.gwemopt_python) is None and not settings.gwemopt_cache_dir:
        raise MissingExtra("gwemopt", f"--solvers {','.join(asked)}: no gwemopt interpreter and no "
                                      "[bench] gwemopt_cache_dir",
                           hint=f" (or a Python with gwemopt in ${ENV_PYTHON})")


def run(args: argparse.Namespace) -> int:
    """Run the benchmark, write the CSV, print the summary; the exit status."""
    from ..evaluation.bench import main as bench_main
    from ..outputs import check_outputs

    check_outputs({"-o/--output": args.output})  # a device, FIFO or directory is refused before hours of work
    require_gwemopt(args)
    return bench_main(args)


if __name__ == "__main__":
    sys.exit(main())
