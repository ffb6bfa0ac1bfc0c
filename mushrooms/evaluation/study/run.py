"""The study as a library function: its inputs and settings in, results, tables and figures out.

:func:`run_study` takes plain objects: :class:`StudySettings` (the
benchmark's settings, where results go, the cluster) and
:class:`StudyInputs` (existing maps, an events file to localise, or a
population to simulate).  It opens the Dask client, makes the maps
(:mod:`.population`, :mod:`.localisation`), runs the task graph
(:mod:`.graph`), and writes ``results.csv``, ``tables.md`` and the figures
under ``settings.out``.  It prints nothing: what a person should see while
it runs goes to ``notify``, and the rest is in the :class:`StudyOutcome`
that ``mushrooms study`` (:mod:`mushrooms.tool.study`) prints.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from ..bench.rows import write_csv
from ..bench.settings import BenchSettings
from .figures import make_figures
from .graph import StudyRun, open_client, run_graph
from .localisation import DEFAULT_EVENTS, Localisation, MapTask, maps_from_directory, maps_from_events
from .population import Population, coinc_ids, simulate_population
from .store import ResultStore
from .tables import paper_tables

__all__ = ["StudySettings", "StudyInputs", "StudyOutcome", "run_study", "study_bench_settings",
           "default_cache_dir"]

log = logging.getLogger(__package__)

Record = dict[str, Any]


def default_cache_dir() -> Path:
    """Where populations and localised maps are cached: ``$MUSHROOMS_CACHE_DIR/study``, else
    ``$CACHE_DIRECTORY/study`` (systemd), else ``~/.cache/mushrooms/study``."""
    base = os.environ.get("MUSHROOMS_CACHE_DIR") or os.environ.get("CACHE_DIRECTORY") or "~/.cache/mushrooms"
    return Path(base).expanduser() / "study"


@dataclass(frozen=True)
class StudySettings:
    """How a study runs.

    Attributes
    ----------
    bench : BenchSettings
        Rows, planning configuration and scoring (the study scores with the
        fixed source model only and one solver thread: :func:`study_bench_settings`).
    out : pathlib.Path
        Results, tables and figures.
    cache : pathlib.Path
        Simulated populations and localised maps (:func:`default_cache_dir`).
    workers : int
        Worker processes of the local cluster (one thread each).
    scheduler : str or None
        Address of a running Dask scheduler instead of a local cluster.
    dashboard : bool
        Serve the local cluster's dashboard on a free port.
    figures : bool
        Write the figures.
    progress : bool
        tqdm bars on stderr.
    localisation : Localisation
        ``bayestar-localize-coincs`` options of maps still to localise.
    """

    bench: BenchSettings
    out: Path
    cache: Path = field(default_factory=default_cache_dir)
    workers: int = 2
    scheduler: str | None = None
    dashboard: bool = False
    figures: bool = True
    progress: bool = False
    localisation: Localisation = field(default_factory=Localisation)

    def __post_init__(self) -> None:
        if not self.scheduler and self.workers < 1:
            raise ValueError(f"workers must be >= 1, got {self.workers}")


@dataclass(frozen=True)
class StudyInputs:
    """Where a study's sky maps come from: one of ``maps``, ``events``, ``simulate`` (default: the packaged events).

    Attributes
    ----------
    maps : str or None
        A directory of existing sky maps (no localisation).
    events : str or None
        An events file whose coincidences are localised (default
        :data:`~.localisation.DEFAULT_EVENTS`).
    simulate : Population or None
        A population to simulate, then localise.
    detections : int or None
        With ``simulate``: realise chunks until they hold this many
        coincidences, and localise those.
    only_simulate : bool
        With ``simulate``: stop after the simulation.
    limit : int or None
        Only the first maps.
    """

    maps: str | None = None
    events: str | None = None
    simulate: Population | None = None
    detections: int | None = None
    only_simulate: bool = False
    limit: int | None = None

    def __post_init__(self) -> None:
        if sum(x is not None for x in (self.maps, self.events, self.simulate)) > 1:
            raise ValueError("one source of sky maps: maps, events or simulate")
        if (self.only_simulate or self.detections is not None) and self.simulate is None:
            raise ValueError("only_simulate and detections go with simulate")
        for name in ("detections", "limit"):
            if (value := getattr(self, name)) is not None and value < 1:
                raise ValueError(f"{name} must be >= 1, got {value}")


@dataclass
class StudyOutcome:
    """What :func:`run_study` did.

    Attributes
    ----------
    n_maps : int
        Maps of the study (0 after ``only_simulate``).
    run : StudyRun or None
        The task graph's rows and counts (None after ``only_simulate``).
    realized : list of dict
        Records of the simulation's realised chunks (empty without a simulation).
    events_files : list of str
        The simulation's events files taken (empty without a simulation).
    tables : str
        The paper's tables (Markdown; empty after ``only_simulate``).
    footer : str
        The run's counts and times, as written under the tables.
    figures : list of pathlib.Path
        Figures written.
    stages : dict
        Wall time per stage (s).
    """

    n_maps: int = 0
    run: StudyRun | None = None
    realized: list[Record] = field(default_factory=list)
    events_files: list[str] = field(default_factory=list)
    tables: str = ""
    footer: str = ""
    figures: list[Path] = field(default_factory=list)
    stages: dict[str, float] = field(default_factory=dict)

    @property
    def simulated_coincidences(self) -> int:
        """Coincidences in the simulation's events files taken."""
        return sum(len(coinc_ids(f)) for f in self.events_files)


def study_bench_settings(bench: BenchSettings) -> BenchSettings:
    """The benchmark's settings as a study uses them: the fixed source model only (no v1 scoring), and one
    solver thread per worker when the configuration says ``threads = 0`` (all cores)."""
    cfg = bench.config
    if getattr(cfg, "threads", 1) == 0:  # one thread per worker: HiGHS too
        bench = dataclasses.replace(bench, config=dataclasses.replace(cfg, threads=1))
    return dataclasses.replace(bench, bench=dataclasses.replace(bench.bench, legacy_scoring=False))


def run_study(settings: StudySettings, inputs: StudyInputs,
              notify: Callable[[str], None] | None = None) -> StudyOutcome:
    """Run a study: make or take the sky maps, plan and score them on Dask, write results, tables, figures.

    Parameters
    ----------
    settings : StudySettings
        Rows, scoring, output and cache directories, the cluster.
    inputs : StudyInputs
        The maps.
    notify : callable, optional
        Told in one line what is about to happen (the simulation, the size
        of the graph); default: the log.

    Returns
    -------
    StudyOutcome
        What ran, the tables and the figures written.

    Raises
    ------
    InputError
        A directory without sky maps, an events file without coincidences.
    SimulationError
        A simulation tool failed.
    """
    tell = notify or log.info
    bench = study_bench_settings(settings.bench)
    outcome = StudyOutcome()
    maps = maps_from_directory(inputs.maps) if inputs.maps else []
    t0 = time.perf_counter()
    client = open_client(settings.workers, settings.scheduler, dashboard=settings.dashboard)
    try:
        if not inputs.maps:
            maps = _localised_maps(settings, inputs, client, outcome, tell, t0)
            if inputs.only_simulate:
                return outcome
        if inputs.limit:
            maps = maps[:inputs.limit]
        tell(f"{len(maps)} map(s) x {len(bench.solvers)} solver(s) on "
             f"{settings.scheduler or f'a local cluster of {settings.workers} worker(s)'}")
        t1 = time.perf_counter()
        outcome.run = run_graph(client, maps, bench, settings.out, settings.localisation, progress=settings.progress)
        outcome.stages["localise_plan_score_s"] = time.perf_counter() - t1
    finally:
        _close(client, settings)
    outcome.n_maps = len(maps)
    _write_results(settings, bench, outcome, time.perf_counter() - t0)
    return outcome


def _close(client: Any, settings: StudySettings) -> None:
    """Close the client, and the local cluster it runs on (never a scheduler it was only given)."""
    client.close()
    cluster = getattr(client, "cluster", None)
    if cluster is not None and not settings.scheduler:
        cluster.close()


def _localised_maps(settings: StudySettings, inputs: StudyInputs, client: Any, outcome: StudyOutcome,
                    tell: Callable[[str], None], t0: float) -> list[MapTask]:
    """The maps of an events file, or of a simulated population (recorded in ``outcome``)."""
    from ...scheduler_core.errors import InputError

    if inputs.simulate is not None:
        files = _simulate(settings, inputs, client, outcome, tell, t0)
        if inputs.only_simulate:
            return []
    else:
        files = [str(inputs.events or DEFAULT_EVENTS)]
    maps: list[MapTask] = []
    for f in files:
        maps += maps_from_events(f, settings.cache, settings.localisation, coinc_ids(f))
    if not maps:
        raise InputError(f"{', '.join(files)}: no coincidences")
    if inputs.detections:
        maps = maps[:inputs.detections]
    return maps


def _simulate(settings: StudySettings, inputs: StudyInputs, client: Any, outcome: StudyOutcome,
              tell: Callable[[str], None], t0: float) -> list[str]:
    """Simulate the population on the cluster; its events files (the realised chunks logged under ``out``)."""
    population = inputs.simulate
    assert population is not None
    directory = settings.cache / "populations"
    tell(f"simulating {population.n_injections} injections (seed {population.seed}, chunks of {population.chunk}"
         + (f", until {inputs.detections} coincidences" if inputs.detections else "") + f") -> {directory}")
    jobs = max(1, sum(client.nthreads().values()))
    files, outcome.realized = simulate_population(population, directory, client, detections=inputs.detections,
                                                  jobs=jobs, progress=settings.progress)
    sim_log = ResultStore(settings.out / "realizations.jsonl")
    for rec in outcome.realized:
        sim_log.append(dict(kind="realization", population=dataclasses.asdict(population), **rec))
    outcome.stages["simulate_s"] = time.perf_counter() - t0
    outcome.events_files = list(files)
    return files


def _write_results(settings: StudySettings, bench: BenchSettings, outcome: StudyOutcome, wall: float) -> None:
    """``results.csv``, ``tables.md`` (the tables and the footer) and the figures."""
    run = outcome.run
    assert run is not None
    out = settings.out
    write_csv(run.rows, out / "results.csv")
    outcome.tables = paper_tables(run.rows, tuple(bench.bench.lightcurves))
    outcome.footer = _footer(bench, outcome, wall)
    (out / "tables.md").write_text(outcome.tables + "\n\n" + outcome.footer + "\n")
    if settings.figures and run.rows:
        outcome.figures = make_figures(run.rows, out / "figures")


def _footer(bench: BenchSettings, outcome: StudyOutcome, wall: float) -> str:
    """The run in one line: maps, rows, tasks, localisations, simulation, wall time per stage."""
    run, realized = outcome.run, outcome.realized
    assert run is not None
    cpu = [r["cpu_s"] for r in run.localisations if not r.get("cached")]
    return (f"{outcome.n_maps} map(s), solvers {','.join(bench.solvers)}, {bench.n_injections} injections/map; "
            f"this run: {len(run.executed)} (map, solver) task(s), {len(run.failed)} failed, "
            f"{len(cpu)} localisation(s)" + (f" (CPU median {sorted(cpu)[len(cpu) // 2]:.0f} s, "
                                             f"total {sum(cpu):.0f} s)" if cpu else "")
            + (f"; {sum(r['injections'] for r in realized)} injection(s) realised in {len(realized)} chunk(s), "
               f"{sum(r['coincidences'] for r in realized)} coincidence(s), CPU "
               f"{sum(r['cpu_s'] for r in realized):.0f} s" if realized else "")
            + f"; wall {wall:.0f} s " + json.dumps({k: round(v, 1) for k, v in outcome.stages.items()}))
