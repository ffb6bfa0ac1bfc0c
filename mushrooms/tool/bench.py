"""``mushrooms bench SKYMAP_DIR``: schedule quality and kilonova detection efficiency (:mod:`mushrooms.evaluation.bench`).

The command line and ``config.toml`` (``[scheduler]``, ``[bench]``) become
a :class:`~mushrooms.evaluation.bench.settings.BenchSettings`;
:func:`~mushrooms.evaluation.bench.run.run_bench` plans and scores; this
module writes the CSV and prints the summary and the figures' paths.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import TYPE_CHECKING, Any, Sequence

from .settings_flag import add_set_option
from .common import MissingExtra, add_common_options, execute, tool_parser

if TYPE_CHECKING:
    from ..evaluation.bench.settings import BenchSettings
    from .config import Config

__all__ = ["HELP", "parser", "run", "main", "bench_settings", "require_gwemopt"]

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
                   help="comma list of greedy,slots,blocks,hybrid,milp,service,gwemopt,gwemopt-repaired "
                        "(service: what the daemon publishes, its anytime flow); ours as "
                        "make_plan publishes them under the config (objective included), or with the "
                        "objective forced by -coverage / -detection (hybrid-coverage); any of ours under an "
                        "arm as ROW@ARM (hybrid@menu: the plan make_plan publishes under the config with the "
                        "arm's [scheduler] keys, see --arm); paired differences are against the first row")
    p.add_argument("--arm", action="append", default=[], metavar="ARM:KEY=VALUE",
                   help="define (or extend) an arm: a [scheduler] key replaced for the rows ROW@ARM, VALUE in "
                        "TOML (repeatable; adds to [bench.arms.ARM]). Fixed 300 s vs the exposure menu: "
                        "--solvers hybrid,hybrid@menu --arm 'menu:exposure_menu_s=[30,60,120,300,600]' "
                        "(expected detections, efficiency and coverage of hybrid@menu paired against hybrid)")
    p.add_argument("--jobs", type=int, default=1, metavar="N", help="maps in parallel processes")
    p.add_argument("--injections", type=int, default=10000, metavar="N", help="kilonova injections per map")
    p.add_argument("--plots", metavar="DIR", help="write the summary figures here")
    p.add_argument("-o", "--output", metavar="FILE", default="results.csv")
    add_set_option(p)
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms bench`` on its own."""
    return execute("bench", parser().parse_args(args), run)


def bench_settings(args: argparse.Namespace, config: "Config") -> "BenchSettings":
    """The run's settings: ``[scheduler]`` and ``[bench]`` of ``config``, and ``--solvers``, ``--injections``,
    ``--start`` (``--jobs`` is checked too); :class:`~mushrooms.scheduler_core.errors.InputError` naming the
    option when one is wrong.  ``mushrooms study`` reads the same options with it.  Both plan on the
    deterministic budget whatever ``[scheduler] deterministic`` says (an arm may set it false)."""
    from ..evaluation.bench.settings import BenchSettings, check_rows
    from ..scheduler_core.errors import InputError

    solvers = tuple(s.strip() for s in str(args.solvers).split(",") if s.strip())
    try:
        check_rows(solvers)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if args.injections < 1:
        raise InputError(f"--injections must be >= 1, got {args.injections}")
    if getattr(args, "jobs", 1) < 1:
        raise InputError(f"--jobs must be >= 1, got {args.jobs}")
    start_iso = None
    if getattr(args, "start", None):
        from ..scheduler_core.times import parse_time

        start_iso = parse_time(args.start, "--start", mjd=True).isot
    bench = with_arms(config.bench, getattr(args, "arm", None) or [])
    scheduler = config.scheduler
    if not scheduler.deterministic:  # rows a referee can make again: the work budget (an arm may still set false)
        import dataclasses
        import sys

        print("note: [scheduler] deterministic = false: bench and study plan on the work budget all the same "
              "(an arm may set deterministic = false)", file=sys.stderr)
        scheduler = dataclasses.replace(scheduler, deterministic=True)
    try:
        return BenchSettings(config=scheduler, bench=bench, solvers=solvers, start_iso=start_iso,
                             n_injections=int(args.injections),
                             supersede_min_gain=float(config.daemon.supersede_min_gain))
    except ValueError as exc:
        raise InputError(str(exc)) from None


def with_arms(bench: Any, specs: Sequence[str]) -> Any:
    """``[bench]`` with the arms of ``--arm ARM:KEY=VALUE`` added (VALUE is TOML: ``[30, 60]``, ``120.0``,
    ``"slots"``); :class:`~mushrooms.scheduler_core.errors.InputError` naming the option when one is wrong."""
    import dataclasses
    import tomllib

    from ..scheduler_core.errors import InputError
    from ..scheduler_core.tables import TableError

    if not specs:
        return bench
    arms = {k: dict(v) for k, v in bench.arms.items()}
    for spec in specs:
        name, colon, assignment = str(spec).partition(":")
        key, eq, value = assignment.partition("=")
        if not (colon and eq and name.strip() and key.strip()):
            raise InputError(f"--arm {spec!r}: expected ARM:KEY=VALUE (e.g. menu:exposure_menu_s=[30,60,120,300,600])")
        try:
            parsed = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"--arm {spec!r}: VALUE is not TOML ({exc})") from None
        arms.setdefault(name.strip(), {})[key.strip()] = parsed
    try:
        return dataclasses.replace(bench, arms=arms)
    except (TableError, ValueError) as exc:
        raise InputError(f"--arm: {exc}") from None


def load_settings(args: argparse.Namespace) -> "BenchSettings":
    """:func:`bench_settings` of the command's config file (``--config``, resolved by :func:`~.common.execute`)."""
    from .config import load_config

    return bench_settings(args, load_config(getattr(args, "config", None), getattr(args, "set", None) or ()))


def require_gwemopt(settings: "BenchSettings") -> None:
    """:class:`MissingExtra` when the rows ask for gwemopt rows that nothing can produce.

    A gwemopt row needs gwemopt's interpreter (this one with the ``gwemopt``
    extra, or ``$MUSHROOMS_GWEMOPT_PYTHON`` / ``[bench] gwemopt_python``) or
    a cache of its schedules (``[bench] gwemopt_cache_dir``, whose misses are
    rows saying ``unavailable``).
    """
    asked = [s for s in settings.solvers if s in GWEMOPT_ROWS]
    if not asked:
        return
    from ..evaluation.gwemopt_baseline import ENV_PYTHON, gwemopt_python

    if gwemopt_python(settings.bench.gwemopt_python) is None and not settings.bench.gwemopt_cache_dir:
        raise MissingExtra("gwemopt", f"--solvers {','.join(asked)}: no gwemopt interpreter and no "
                                      "[bench] gwemopt_cache_dir",
                           hint=f" (or a Python with gwemopt in ${ENV_PYTHON})")


def progress_bars() -> bool:
    """A progress bar on stderr when it is a terminal (``MUSHROOMS_PROGRESS=1`` forces it, ``0`` hides it)."""
    forced = os.environ.get("MUSHROOMS_PROGRESS", "")
    return forced == "1" or (forced != "0" and sys.stderr.isatty())


def _warn_without_gwemopt(settings: "BenchSettings") -> None:
    """One line on stderr when gwemopt rows will come from the cache only (its misses: ``unavailable``)."""
    if not set(GWEMOPT_ROWS) & set(settings.solvers):
        return
    from ..evaluation.gwemopt_baseline import ENV_PYTHON, gwemopt_python

    if gwemopt_python(settings.bench.gwemopt_python) is None:  # (require_gwemopt refuses it without a cache)
        print(f"mushrooms bench: gwemopt unavailable (pip install 'mushrooms[gwemopt]', or set ${ENV_PYTHON} "
              f"to its interpreter); its rows will say 'unavailable' where the cache "
              f"{settings.bench.gwemopt_cache_dir} has no schedule", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """Run the benchmark, write the CSV, print the summary; the exit status.

    0 when every map was processed (individual solver failures are rows in
    the CSV, not errors); bad input raises (exit status 2 through
    :func:`~.common.execute`).
    """
    from ..evaluation.bench.plots import make_plots
    from ..evaluation.bench.rows import write_csv
    from ..evaluation.bench.run import run_bench, skymaps_in
    from ..evaluation.bench.summary import summarize
    from ..outputs import check_outputs

    check_outputs({"-o/--output": args.output})  # a device, FIFO or directory is refused before hours of work
    settings = load_settings(args)
    require_gwemopt(settings)
    paths = skymaps_in(args.skymap_dir)
    _warn_without_gwemopt(settings)
    t0 = time.perf_counter()
    rows = run_bench(settings, paths, jobs=args.jobs, output=args.output, progress=progress_bars())
    write_csv(rows, args.output)
    print(summarize(rows, tuple(settings.bench.lightcurves)))
    _print_footer(settings, paths, args, time.perf_counter() - t0)
    if args.plots:
        for p in make_plots(rows, args.plots):
            print(f"plot: {p}")
    return 0


def _print_footer(settings: "BenchSettings", paths: Sequence[Any], args: argparse.Namespace, wall: float) -> None:
    print(f"\n{len(paths)} map(s), solvers {','.join(settings.solvers)}, jobs {args.jobs}, "
          f"{settings.n_injections} injections/map, wall {wall:.0f} s; CSV: {args.output}")


if __name__ == "__main__":
    sys.exit(main())
