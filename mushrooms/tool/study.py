"""``mushrooms study``: the paper's experiment on a Dask cluster (:mod:`mushrooms.evaluation.study`).

The command line and ``config.toml`` become a
:class:`~mushrooms.evaluation.study.run.StudySettings` and
:class:`~mushrooms.evaluation.study.run.StudyInputs` (checked here, with the
options' names in the errors); :func:`~mushrooms.evaluation.study.run.run_study`
does the work; this module prints the tables, the footer and the figures' paths.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from ..evaluation.study.defaults import DEFAULT_CHUNK, DEFAULT_RECIPE, DEFAULT_SEED, DEFAULT_SOLVERS, RECIPE_NAMES
from .common import add_common_options, execute, require_extra, tool_parser

if TYPE_CHECKING:
    from ..evaluation.bench.settings import BenchSettings
    from ..evaluation.study.run import StudyInputs, StudyOutcome, StudySettings

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
    sp.add_argument("--population", choices=RECIPE_NAMES, default=DEFAULT_RECIPE,
                    help="the recipe of --simulate (noise curves, masses, waveform, cuts) and the localisation "
                         "options of its coincidences (also with --events): o3-bns, the project's O3 BNS; o4, "
                         "O4 HLV BNS+NSBH after Kiendrebeogo et al. 2023; o4-real, O4 as it was (O4a without "
                         "Virgo, real ranges and duty cycles, a FAR-like threshold) (default %(default)s)")
    sp.add_argument("--seed", type=int, default=DEFAULT_SEED, help="seed of --simulate (default %(default)s)")
    sp.add_argument("--intrinsic-samples", type=int, metavar="N",
                    help="with --simulate: N mass-spin points of the recipe's distribution given to "
                         "bayestar-inject --distribution-samples (o3-bns: instead of its preset's 10^4-cell "
                         "horizon grid, ~30 CPU-min; o4: default 1000, ~0.7 CPU-s each)")
    sp.add_argument("--detections", type=int, metavar="N",
                    help="with --simulate: realise chunks of injections in order until they hold N coincidences, "
                         "and localise those N")
    sp.add_argument("--chunk", type=int, default=DEFAULT_CHUNK, metavar="N",
                    help="with --simulate: injections per bayestar-realize-coincs task (default %(default)s)")
    sp.add_argument("--only-simulate", action="store_true",
                    help="with --simulate: stop after the simulation (print its events files)")
    sp.add_argument("--limit", type=int, metavar="N", help="only the first N coincidences / maps")
    sp.add_argument("--solvers", default=",".join(DEFAULT_SOLVERS),
                    help="comma list of greedy,slots,blocks,hybrid,milp,service,gwemopt,gwemopt-repaired "
                         "(service: what the daemon publishes, its anytime flow); ours as "
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


def study_inputs(args: argparse.Namespace) -> "StudyInputs":
    """Where the maps come from (``--maps``, ``--events``, ``--simulate`` and its options, ``--limit``);
    :class:`~mushrooms.scheduler_core.errors.InputError` naming the option when one is wrong."""
    from ..evaluation.study.localisation import DEFAULT_EVENTS
    from ..evaluation.study.recipes import recipe_population
    from ..evaluation.study.run import StudyInputs
    from ..scheduler_core.errors import InputError

    population, events = None, None
    if args.maps:
        pass
    elif args.simulate is not None:
        for option, value in (("--simulate", args.simulate), ("--intrinsic-samples", args.intrinsic_samples),
                              ("--chunk", args.chunk), ("--detections", args.detections)):
            if value is not None and value < 1:
                raise InputError(f"{option} must be >= 1, got {value}")
        population, _ = recipe_population(args.population, args.simulate, seed=args.seed, chunk=args.chunk,
                                          intrinsic_samples=args.intrinsic_samples)
    else:
        events = args.events or str(DEFAULT_EVENTS)
        if not Path(events).is_file():
            raise InputError(f"no such events file: {events}")
    if args.only_simulate and args.simulate is None:
        raise InputError("--only-simulate goes with --simulate")
    if args.detections is not None and args.simulate is None:
        raise InputError("--detections goes with --simulate (for other inputs use --limit)")
    return StudyInputs(maps=args.maps or None, events=events, simulate=population, detections=args.detections,
                       only_simulate=bool(args.only_simulate), limit=args.limit)


def study_settings(args: argparse.Namespace, bench: "BenchSettings") -> "StudySettings":
    """The study's settings: the benchmark's (``bench``: :func:`~.bench.load_settings`) and ``--limit``
    (checked here), ``--out``, ``--cache``, ``--workers``, ``--scheduler``, ``--dashboard``, ``--no-figures``."""
    from ..evaluation.study.recipes import RECIPES
    from ..evaluation.study.run import StudySettings, default_cache_dir
    from ..scheduler_core.errors import InputError
    from .bench import progress_bars

    if args.limit is not None and args.limit < 1:
        raise InputError(f"--limit must be >= 1, got {args.limit}")
    if not args.scheduler and args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}")
    return StudySettings(bench=bench, out=Path(args.out),
                         cache=Path(args.cache) if getattr(args, "cache", None) else default_cache_dir(),
                         workers=args.workers, scheduler=args.scheduler, dashboard=bool(args.dashboard),
                         figures=not args.no_figures, progress=progress_bars(),
                         localisation=RECIPES[getattr(args, "population", DEFAULT_RECIPE)].localisation)


def run(args: argparse.Namespace) -> int:
    """Run the study; print its tables, footer and figures; the exit status.

    0 when every task ran (failed tasks are records, not errors); 1 when the
    simulation fails; bad input raises (exit status 2 through :func:`~.common.execute`).
    """
    from .bench import load_settings, require_gwemopt

    if not getattr(args, "maps", None):  # simulate and/or localise (bayestar-*): lalsuite, igwn-ligolw
        require_extra("simulate")
    require_extra("study")  # the task graph on Dask distributed
    bench = load_settings(args)
    require_gwemopt(bench)
    settings = study_settings(args, bench)
    inputs = study_inputs(args)
    from ..evaluation.study.population import SimulationError
    from ..evaluation.study.run import run_study

    try:
        outcome = run_study(settings, inputs, notify=lambda line: print(line, file=sys.stderr))
    except SimulationError as exc:
        print(f"mushrooms study: simulation failed: {exc}", file=sys.stderr)
        return 1
    if inputs.only_simulate:
        _print_simulation(outcome)
    else:
        print(outcome.tables)
        print("\n" + outcome.footer)
        for p in outcome.figures:
            print(f"figure: {p}")
    return 0


def _print_simulation(outcome: "StudyOutcome") -> None:
    """``--only-simulate``: what was realised, and the events files taken."""
    realized = outcome.realized
    print(f"simulated: {sum(r['injections'] for r in realized)} injection(s) realised in "
          f"{len(realized)} chunk(s), {len(outcome.events_files)} chunk(s) taken, "
          f"{outcome.simulated_coincidences} coincidence(s) in them; "
          f"CPU {sum(r['cpu_s'] for r in realized):.0f} s; wall {outcome.stages['simulate_s']:.0f} s")
    for f in outcome.events_files:
        print(f)


if __name__ == "__main__":
    sys.exit(main())
