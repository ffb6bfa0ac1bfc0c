"""``mushrooms study``: the paper's experiment at population scale, as a Dask task graph.

Stages (each a task, or one task per event / per (map, solver)):

(a) **sky maps** — one of

    * a new population simulated with ligo.skymap's own command-line tools
      (``bayestar-sample-model-psd`` → ``bayestar-inject`` → one
      ``bayestar-realize-coincs`` task per chunk of injections, realised in
      order until they hold the coincidences asked for; the O3 BNS recipe of
      ``shared/data/skymaps/simulated/SOURCES.md``, see :class:`Population`
      and :func:`simulate_population`),
    * a file of realised coincidences (``events.xml.gz``; default the packaged
      O3 BNS population :data:`DEFAULT_EVENTS`: 600 injections, 21
      coincidences), localised one task per coincidence with
      ``bayestar-localize-coincs --coinc-event-id`` (``OMP_NUM_THREADS=1``),
      each map cached on disk keyed by (events file hash, coinc id,
      localisation options), so a planning study never localises twice,
    * or a directory of existing sky maps;

(b)+(c) **plan and score** — one task per (map, solver): the benchmark's own
    :func:`mushrooms.evaluation.bench.bench_map` on that map with that one solver
    (coverage by the independent checker, kilonova efficiencies of the
    bench's light curves with the fixed source model, the certified
    coverage upper bound);

(d) **tables and figures** in the paper's layout (:func:`paper_tables`,
    :func:`make_figures`).

Every finished (map, solver) result is appended at once to
``<out>/results.jsonl`` (flushed and fsynced) with the software versions of
the worker that made it and the configuration; a rerun skips every key
already there with a scored result, and retries the failures.  A task that
fails is recorded with its error and the last frames of its traceback; the
others go on.

The engine is Dask distributed: a :class:`distributed.LocalCluster` of
``--workers`` single-threaded worker processes by default, or any running
scheduler with ``--scheduler ADDRESS`` (e.g. one started by dask-jobqueue on
a Slurm or HTCondor site; see ``benchmarks/README.md``).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import functools
import hashlib
import json
import logging
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from . import bench
from ..scheduler_core.plan import strict_json
from .study_defaults import DEFAULT_SEED

__all__ = [
    "DEFAULT_EVENTS",
    "Population",
    "Localisation",
    "MapTask",
    "ResultStore",
    "simulate_population",
    "SimulationError",
    "inject_population",
    "realize_chunk",
    "split_injections",
    "chunks_needed",
    "coinc_ids",
    "localise",
    "plan_and_score",
    "run_study",
    "paper_tables",
    "make_figures",
    "open_client",
    "main",
]

log = logging.getLogger(__name__)

#: The O3 BNS population of ``shared/data/skymaps/simulated/bns_o3_pipeline/``: the realised
#: coincidences (21) of its first 600 injections (packaged; see ``data/populations/SOURCES.md``).
DEFAULT_EVENTS = Path(__file__).resolve().parent.parent / "data" / "populations" / "bns_o3" / "events.xml.gz"
#: Frames of a failed task's traceback kept in its record.
TRACEBACK_FRAMES = 4
#: Packages whose versions every record carries.
VERSIONED = ("mushrooms", "ligo.skymap", "highspy", "numpy", "astropy", "dask", "distributed", "lalsuite")


# --------------------------------------------------------------------------- helpers


def _sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _digest(obj: Any, n: int = 16) -> str:
    """Short stable hash of a JSON-able object."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:n]


@functools.lru_cache(maxsize=1)
def software_versions() -> dict[str, str]:
    """Versions of the packages a result depends on (``"-"`` when not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in VERSIONED:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "-"
    return out


def _die_with_parent() -> None:  # pragma: no cover - runs in the child between fork and exec
    """Linux: the tool gets SIGKILL when the worker that started it dies (no orphaned BAYESTAR runs)."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:
        pass


def _run_tool(cmd: Sequence[str], cwd: str | Path | None = None, omp_threads: int | None = None) -> float:
    """Run one ligo.skymap tool; its CPU time (s, children's user+sys); raise with its stderr tail.

    The tool runs in a session of its own, is killed with its process group
    when the calling thread is interrupted, and (on Linux) dies with the
    worker process that started it.
    """
    import signal

    env = dict(os.environ)
    if omp_threads is not None:
        env["OMP_NUM_THREADS"] = str(omp_threads)
    exe = shutil.which(cmd[0])
    if exe is None:
        raise RuntimeError(f"{cmd[0]} not found on PATH (ligo.skymap with lalsuite: pip install 'mushrooms[simulate]')")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.Popen([exe, *cmd[1:]], cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True,
                            preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
    try:
        stdout, stderr = proc.communicate()
    except BaseException:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
        raise
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        tail = " | ".join((stderr or stdout).strip().splitlines()[-3:])
        raise RuntimeError(f"{cmd[0]} exited {proc.returncode}: {tail}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


# --------------------------------------------------------------------------- stage (a): sky maps


@dataclass(frozen=True)
class Population:
    """A simulated population: ligo.skymap's recipe for O3-like BNS mergers.

    The defaults are the commands of ``shared/data/skymaps/simulated/SOURCES.md``
    (network H1, L1, V1 with the O3 noise curves scaled as there; single-detector
    threshold 4 at injection, network SNR >= 8 with 70 % duty cycle at
    realisation).  The injections are realised in chunks of ``chunk``
    consecutive injections, one ``bayestar-realize-coincs`` task each, chunk
    ``k`` with seed ``seed + 1 + k`` (so a chunk's coincidences do not depend
    on how many workers there are, nor on how many chunks are realised).

    Attributes
    ----------
    n_injections : int
        ``bayestar-inject --nsamples``: injections drawn.
    seed : int
        Seed of the injections (and, offset by chunk, of their realisation).
    distribution : str
        ``bayestar-inject --distribution``.
    waveform : str
        Waveform approximant of the injections.
    psd_scales : tuple of (detector, model, scale)
        ``bayestar-sample-model-psd`` noise curves.
    duty_cycle : float
        Single-detector duty cycle.
    net_snr_threshold : float
        Network SNR threshold of a detection.
    intrinsic_samples : int or None
        None: ``--distribution`` (the preset; the tool first computes the
        horizon on a 10^4-cell mass-spin grid, ~0.19 s of CPU per cell here,
        ~30 CPU-min). N: draw N (mass1, mass2, spin1z, spin2z) points from the
        same preset's distributions (``bns_astro``: masses normal(1.33, 0.09)
        Msun within [1, 2], aligned spins uniform in [-0.05, 0.05]; seeded)
        and pass them with ``--distribution-samples`` (N horizons instead).
    chunk : int
        Injections per realisation task (~1.2 s of CPU per injection here).
    """

    n_injections: int = 1000
    seed: int = DEFAULT_SEED
    distribution: str = "bns_astro"
    waveform: str = "TaylorF2threePointFivePN"
    psd_scales: tuple[tuple[str, str, float], ...] = (
        ("H1", "aLIGO140MpcT1800545", 0.80), ("L1", "aLIGO140MpcT1800545", 0.95), ("V1", "AdVO3LowT1800545", 0.80))
    duty_cycle: float = 0.7
    net_snr_threshold: float = 8.0
    intrinsic_samples: int | None = None
    chunk: int = 50

    def key(self) -> str:
        """Cache key of the injections (the realisation chunk size is not part of it)."""
        d = dataclasses.asdict(self)
        d.pop("chunk")
        return _digest(d)

    def chunks(self) -> list[tuple[int, int]]:
        """The realisation chunks: ``(start, stop)`` injection indices, in order."""
        if self.chunk < 1:
            raise ValueError(f"chunk must be >= 1, got {self.chunk}")
        return [(a, min(a + self.chunk, self.n_injections)) for a in range(0, self.n_injections, self.chunk)]


def inject_population(population: Population, directory: str | Path, jobs: int = 1) -> str:
    """Noise curves and injections with ligo.skymap's tools; the path of ``injections.xml`` (cached).

    Writes ``psds.xml`` and ``injections.xml`` in ``directory /
    population.key()`` (the injections last, by rename, so a half-made file is
    never taken for a finished one).  ``jobs``: ``bayestar-inject -j``
    (processes for its horizon computation).
    """
    d = Path(directory) / population.key()
    injections = d / "injections.xml"
    if injections.exists():
        return str(injections)
    d.mkdir(parents=True, exist_ok=True)
    meta = dataclasses.asdict(population)
    meta.pop("chunk")
    (d / "population.json").write_text(strict_json.dumps(meta, indent=1))
    psd = ["bayestar-sample-model-psd", "-o", "psds.xml"]
    for det, model, scale in population.psd_scales:
        psd += [f"--{det}", model, f"--{det}-scale", str(scale)]
    _run_tool(psd, cwd=d)
    if population.intrinsic_samples:
        _write_intrinsic_samples(population, d / "intrinsic_samples.ecsv")
        source = ["--distribution-samples", "intrinsic_samples.ecsv"]
    else:
        source = ["--distribution", population.distribution]
    _run_tool(["bayestar-inject", "-l", "error", "--seed", str(population.seed),
               *source, "--reference-psd", "psds.xml",
               "--waveform", population.waveform, "--snr-threshold", "4", "--min-triggers", "1",
               "--nsamples", str(population.n_injections), "-j", str(max(1, int(jobs))),
               "-o", "injections.partial.xml"], cwd=d, omp_threads=1)
    os.replace(d / "injections.partial.xml", injections)
    return str(injections)


def split_injections(injections: str | Path, start: int, stop: int, target: str | Path) -> int:
    """Write injections ``[start, stop)`` of a LIGO-LW injection file to ``target``; how many.

    Every other table (process, process_params) is kept, so the chunk is a
    valid input of ``bayestar-realize-coincs``.
    """
    from igwn_ligolw import lsctables
    from igwn_ligolw import utils as ligolw_utils
    from ligo.skymap.io.events.ligolw import ContentHandler

    doc = ligolw_utils.load_filename(str(injections), contenthandler=ContentHandler)
    table = lsctables.SimInspiralTable.get_table(doc)
    rows = list(table)[start:stop]
    table[:] = rows
    ligolw_utils.write_filename(doc, str(target), trap_signals=None)  # runs in worker threads: no signal traps
    return len(rows)


def realize_chunk(population: Population, injections: str, k: int) -> dict[str, Any]:
    """Realise chunk ``k`` of a population's injections (``bayestar-realize-coincs``; cached).

    Returns
    -------
    dict
        ``chunk``, ``events`` (the chunk's ``events.xml.gz``), ``injections``
        (in the chunk), ``coincidences``, ``cpu_s``, ``wall_s``, ``cached``.
    """
    start, stop = population.chunks()[k]
    d = Path(injections).parent / f"realized-{population.chunk}"
    events = d / f"events-{k:04d}.xml.gz"
    if events.exists():
        return dict(chunk=k, events=str(events), injections=stop - start, coincidences=len(coinc_ids(events)),
                    cpu_s=0.0, wall_s=0.0, cached=True)
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=d, prefix=f".{k:04d}-") as tmp:
        part = Path(tmp) / "injections.xml"
        split_injections(injections, start, stop, part)
        cpu = _run_tool(["bayestar-realize-coincs", "--seed", str(population.seed + 1 + k), "-j", "1", "-l", "error",
                         "-o", "events.xml.gz", "injections.xml", "--reference-psd",
                         str(Path(injections).parent / "psds.xml"),
                         "--snr-threshold", "1", "--net-snr-threshold", str(population.net_snr_threshold),
                         "--min-triggers", "1", "--duty-cycle", str(population.duty_cycle), "--keep-subthreshold",
                         "--measurement-error", "gaussian-noise", "--detector",
                         *[det for det, _, _ in population.psd_scales]], cwd=tmp, omp_threads=1)
        n = len(coinc_ids(Path(tmp) / "events.xml.gz"))
        os.replace(Path(tmp) / "events.xml.gz", events)
    return dict(chunk=k, events=str(events), injections=stop - start, coincidences=n, cpu_s=round(cpu, 2),
                wall_s=round(time.perf_counter() - t0, 2), cached=False)


def chunks_needed(coincidences: Mapping[int, int], n_chunks: int, target: int | None) -> int | None:
    """How many leading chunks make the population, once that is known.

    Parameters
    ----------
    coincidences : mapping
        Coincidences found per realised chunk index (any order, gaps allowed).
    n_chunks : int
        Chunks of the whole injection set.
    target : int or None
        Coincidences wanted (None: every chunk).

    Returns
    -------
    int or None
        The smallest ``K`` whose chunks ``0 .. K-1`` hold at least ``target``
        coincidences, if those chunks are all realised; ``n_chunks`` when all
        are realised and still short of it; None while it cannot be known yet.
        The answer depends only on the chunks' contents, not on the order they
        finished in (so neither on the number of workers).
    """
    total = 0
    for k in range(n_chunks):
        if k not in coincidences:
            return None
        total += coincidences[k]
        if target is not None and total >= target:
            return k + 1
    return n_chunks


#: How often (s) the client looks at the simulation's tasks.
POLL_S = 0.2


def _result(fut: Any) -> Any:
    """A future's result, waited for by polling (a blocking wait in the client does not see Ctrl-C)."""
    while not fut.done():
        time.sleep(POLL_S)
    return fut.result()


class SimulationError(RuntimeError):
    """A simulation tool failed: the study has no population to go on with."""


def simulate_population(population: Population, directory: str | Path, client: Any = None,
                        detections: int | None = None, jobs: int = 1,
                        progress: bool = False) -> tuple[list[str], list[dict[str, Any]]]:
    """Inject and realise a population; its events files, in chunk order, and the chunks' records.

    Injection is one task (``bayestar-inject -j jobs``); realisation one task
    per chunk of :attr:`Population.chunk` injections, at most as many in flight
    as the cluster has threads, in chunk order, until the leading chunks hold
    ``detections`` coincidences (:func:`chunks_needed`; None: all chunks).
    Everything is cached under ``directory / population.key()``.

    Parameters
    ----------
    population : Population
        The recipe.
    directory : path
        Cache of populations.
    client : distributed.Client, optional
        The cluster; None runs the tools here, one after the other.
    detections : int, optional
        Coincidences wanted.
    jobs : int
        Processes for ``bayestar-inject``.
    progress : bool
        A tqdm bar over the chunks on stderr.
    """
    from tqdm import tqdm

    n_chunks = len(population.chunks())
    if client is None:
        try:
            injections = inject_population(population, directory, jobs)
        except Exception as exc:
            raise SimulationError(f"injecting: {type(exc).__name__}: {exc}") from exc
        records: dict[int, dict[str, Any]] = {}
        for k in range(n_chunks):
            try:
                records[k] = realize_chunk(population, injections, k)
            except Exception as exc:
                raise SimulationError(f"realising chunk {k}: {type(exc).__name__}: {exc}") from exc
            if chunks_needed({i: r["coincidences"] for i, r in records.items()}, n_chunks, detections) is not None:
                break
    else:
        inject = client.submit(inject_population, population, str(directory), jobs,
                               key=f"inject-{population.key()}", pure=False)
        try:
            injections = _result(inject)
        except Exception as exc:
            raise SimulationError(f"injecting: {type(exc).__name__}: {exc}") from exc
        slots = max(1, sum(client.nthreads().values()))
        records = {}
        nxt = 0
        inflight: list[Any] = []
        bar = tqdm(total=n_chunks, desc="realise", unit="chunk", disable=not progress, file=sys.stderr)
        try:
            while True:
                found = sum(r["coincidences"] for r in records.values())  # of chunks < nxt: a lower bound
                while nxt < n_chunks and len(inflight) < slots and (detections is None or found < detections):
                    inflight.append(client.submit(realize_chunk, population, injections, nxt,
                                                  key=f"realize-{population.key()}-{population.chunk}-{nxt}",
                                                  pure=False))
                    nxt += 1
                if not inflight:
                    break
                done = [f for f in inflight if f.done()]
                if not done:
                    time.sleep(POLL_S)  # polled, not blocked in the client: Ctrl-C reaches us
                    continue
                for fut in done:
                    inflight.remove(fut)
                    if fut.status != "finished":
                        raise SimulationError(f"realising {fut.key}: {type(fut.exception()).__name__}: "
                                              f"{fut.exception()}")
                    rec = fut.result()
                    records[rec["chunk"]] = rec
                    bar.update(1)
                    bar.set_postfix_str(f"{sum(r['coincidences'] for r in records.values())} coincidences")
                    fut.release()
        finally:
            bar.close()
            for fut in inflight:
                fut.cancel()
    counts = {i: r["coincidences"] for i, r in records.items()}
    used = chunks_needed(counts, n_chunks, detections) or n_chunks
    used = min(used, len(records))
    chosen = [records[k] for k in range(used) if k in records]
    return [r["events"] for r in chosen], [records[k] for k in sorted(records)]


def _write_intrinsic_samples(population: Population, path: Path) -> None:
    """N points of the ``bns_astro`` mass and spin distributions (bayestar-inject's own constants)."""
    import numpy as np
    from astropy.table import Table

    if population.distribution != "bns_astro":
        raise ValueError(f"intrinsic_samples is implemented for bns_astro, not {population.distribution}")
    rng = np.random.default_rng(population.seed)
    n = int(population.intrinsic_samples or 0)
    masses = rng.normal(1.33, 0.09, size=(4 * n + 16, 2))
    masses = masses[np.all((masses >= 1.0) & (masses <= 2.0), axis=1)][:n]  # the preset's mass range
    spins = rng.uniform(-0.05, 0.05, size=(n, 2))
    Table({"mass1": masses[:, 0], "mass2": masses[:, 1], "spin1z": spins[:, 0], "spin2z": spins[:, 1]}).write(
        path, format="ascii.ecsv", overwrite=True)


def coinc_ids(events: str | Path) -> list[int]:
    """The coincidences of an events file, as ``bayestar-localize-coincs`` reads them (sorted)."""
    from ligo.skymap.io import events as gw_events

    logging.getLogger("BAYESTAR").setLevel(logging.ERROR)  # its phase-convention notice, once per file
    return sorted(int(k) for k in gw_events.open(str(events)))


@dataclass(frozen=True)
class Localisation:
    """Options of ``bayestar-localize-coincs`` (part of the map cache key).

    Attributes
    ----------
    f_low : float
        Low frequency cutoff (Hz).
    waveform : str
        Template approximant.
    extra : tuple of str
        Further options passed as they are.
    """

    f_low: float = 25.0
    waveform: str = "TaylorF2threePointFivePN"
    extra: tuple[str, ...] = ()

    def arguments(self) -> list[str]:
        """The command-line options."""
        return ["--f-low", repr(self.f_low), "--waveform", self.waveform, *self.extra]

    def key(self) -> str:
        """Cache key of these options."""
        return _digest(self.arguments())


def localised_path(cache: str | Path, events_sha256: str, coinc_id: int, options: Localisation) -> Path:
    """Where the map of one coincidence is cached: keyed by events hash, coinc id and options."""
    return Path(cache) / "maps" / f"{events_sha256[:16]}-{options.key()}" / f"{coinc_id}.fits"


def localise(events: str, coinc_id: int, options: Localisation, target: str) -> dict[str, Any]:
    """Localise one coincidence with BAYESTAR into ``target`` (atomic; a no-op when cached).

    Runs ``bayestar-localize-coincs EVENTS --coinc-event-id ID`` with
    ``OMP_NUM_THREADS=1`` (one core per worker).

    Returns
    -------
    dict
        ``path``, ``coinc_id``, ``cpu_s`` (the tool's CPU time), ``wall_s``,
        ``cached`` (True when the map was already there).
    """
    out = Path(target)
    if out.exists():
        return dict(path=str(out), coinc_id=coinc_id, cpu_s=0.0, wall_s=0.0, cached=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=out.parent, prefix=f".{coinc_id}-") as tmp:
        cpu = _run_tool(["bayestar-localize-coincs", str(events), "--coinc-event-id", str(coinc_id),
                         "-o", tmp, "-l", "error", *options.arguments()], omp_threads=1)
        made = Path(tmp) / f"{coinc_id}.fits"
        if not made.exists():
            raise RuntimeError(f"bayestar-localize-coincs wrote no {made.name} for coinc {coinc_id}")
        os.replace(made, out)
    return dict(path=str(out), coinc_id=coinc_id, cpu_s=round(cpu, 2), wall_s=round(time.perf_counter() - t0, 2),
                cached=False)


@dataclass(frozen=True)
class MapTask:
    """One sky map of the study: an existing file, or a coincidence still to localise.

    Attributes
    ----------
    key : str
        Identity of the map in the result store (file hash, or events hash,
        coinc id and localisation options).
    name : str
        Shown in tables (the file path).
    path : str
        The sky map file (for a coincidence: its cache path, maybe not yet made).
    events : str or None
        Events file to localise from (None: the map exists).
    coinc_id : int or None
        Coincidence to localise.
    """

    key: str
    name: str
    path: str
    events: str | None = None
    coinc_id: int | None = None


def maps_from_directory(directory: str | Path) -> list[MapTask]:
    """The sky maps under a directory (``bench.skymaps_in``: InputError when none), keyed by their bytes."""
    return [MapTask(key=_sha256_file(p)[:24], name=str(p), path=str(p)) for p in bench.skymaps_in(directory)]


def maps_from_events(events: str | Path, cache: str | Path, options: Localisation,
                     ids: Iterable[int] | None = None) -> list[MapTask]:
    """One map per coincidence of an events file (``ids``: a subset), cached under ``cache``."""
    events = str(Path(events).resolve())
    sha = _sha256_file(events)
    ids = coinc_ids(events) if ids is None else list(ids)
    out = []
    for cid in ids:
        path = localised_path(cache, sha, cid, options)
        out.append(MapTask(key=f"{sha[:16]}:{cid}:{options.key()}", name=str(path), path=str(path),
                           events=events, coinc_id=cid))
    return out


# --------------------------------------------------------------------------- stages (b), (c): plan and score


def _traceback_summary(exc: BaseException, frames: int = TRACEBACK_FRAMES) -> str:
    tb = traceback.extract_tb(exc.__traceback__)[-frames:]
    lines = [f"{Path(f.filename).name}:{f.lineno} in {f.name}: {(f.line or '').strip()}" for f in tb]
    return " | ".join(lines + [f"{type(exc).__name__}: {exc}"])[:2000]


def plan_and_score(skymap: str | Mapping[str, Any], solver: str, settings: bench.BenchSettings) -> dict[str, Any]:
    """Plan one map with one solver and score the plan (the bench's :func:`~mushrooms.evaluation.bench.bench_map`).

    Parameters
    ----------
    skymap : str or mapping
        Sky map path, or the result of :func:`localise` (its ``path``).
    solver : str
        One of :data:`mushrooms.evaluation.bench.SOLVERS`.
    settings : BenchSettings
        The study's settings (its ``solvers`` are ignored).

    Returns
    -------
    dict
        ``row`` (the bench's CSV row), ``ok`` (scored), ``error`` and
        ``traceback`` (a failure: a raised exception, or a row the bench
        could not score), ``versions``, ``task_s``.
    """
    bench._worker_init()
    path = skymap["path"] if isinstance(skymap, Mapping) else str(skymap)
    t0 = time.perf_counter()
    try:
        row = bench.bench_map(path, dataclasses.replace(settings, solvers=(solver,)), raise_errors=True)[0]
    except Exception as exc:  # recorded; the study goes on
        row = bench._row(path, solver, status=f"error: {type(exc).__name__}: {exc}"[:300], valid=False)
        return dict(row=row, ok=False, error=f"{type(exc).__name__}: {exc}"[:500],
                    traceback=_traceback_summary(exc), versions=software_versions(),
                    task_s=round(time.perf_counter() - t0, 3))
    ok = bench._scored(row)
    return dict(row=row, ok=ok, error=None if ok else str(row.get("status")), traceback=None,
                versions=software_versions(), task_s=round(time.perf_counter() - t0, 3))


def study_config(settings: bench.BenchSettings) -> dict[str, Any]:
    """The configuration a result depends on (JSON-able; its hash is part of every result key)."""
    d = dataclasses.asdict(settings)
    d.pop("solvers")
    d["config"] = dataclasses.asdict(settings.config)
    d["row_names"] = bench.ROW_NAMES_VERSION  # a row named after a solver changed meaning (issue 24)
    return json.loads(json.dumps(d, sort_keys=True, default=str))


class ResultStore:
    """Append-only JSON-lines file of (map, solver) results: ``<out>/results.jsonl``.

    Each line is one finished task: ``key``, ``map``, ``skymap``, ``solver``,
    ``ok``, ``row``, ``error``, ``traceback``, ``versions``, ``config_hash``,
    ``config``, ``finished`` (UTC).  The last line of a key wins.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)

    def records(self) -> dict[str, dict[str, Any]]:
        """The last record of every key (a torn last line, from a killed run, is ignored)."""
        out: dict[str, dict[str, Any]] = {}
        if not self.path.exists():
            return out
        with open(self.path) as fh:
            for line in fh:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if rec.get("kind") == "result":
                    out[rec["key"]] = rec
        return out

    def append(self, record: Mapping[str, Any]) -> None:
        """Write one record and put it on disk now."""
        with open(self.path, "a") as fh:
            fh.write(strict_json.dumps(record, default=str) + "\n")
            fh.flush()
            os.fsync(fh.fileno())


def result_key(map_key: str, solver: str, config_hash: str) -> str:
    """Identity of one (map, solver) result under one configuration."""
    return f"{map_key}|{solver}|{config_hash}"


def open_client(workers: int = 2, scheduler: str | None = None, dashboard: bool = False) -> Any:
    """A Dask client: on ``scheduler`` if given, else on a new LocalCluster.

    The local cluster has ``workers`` worker processes of one thread each
    (BAYESTAR and HiGHS are told to use one thread too), no dashboard unless
    asked.
    """
    from distributed import Client, LocalCluster

    if not log.isEnabledFor(logging.DEBUG):  # the cluster's own INFO chatter would bury the progress bar
        logging.getLogger("distributed").setLevel(logging.WARNING)
    if scheduler:
        return Client(scheduler)
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=":0" if dashboard else None)
    return Client(cluster)


@dataclass
class StudyRun:
    """What one :func:`run_study` call did.

    Attributes
    ----------
    rows : list of dict
        One bench row per (map, solver) of this study (this run's and earlier
        runs' results), in map then solver order.
    executed : list of str
        Result keys planned in this run (the rest were in the store).
    failed : list of str
        Keys whose task failed in this run.
    localisations : list of dict
        :func:`localise` results of this run (CPU and wall time per map).
    """

    rows: list[dict[str, Any]]
    executed: list[str]
    failed: list[str]
    localisations: list[dict[str, Any]]


def run_study(client: Any, maps: Sequence[MapTask], settings: bench.BenchSettings, out: str | Path,
              localisation: Localisation | None = None, progress: bool = True) -> StudyRun:
    """Plan and score every (map, solver) not yet in ``<out>/results.jsonl`` on a Dask cluster.

    Maps still to localise get one localisation task each; each (map,
    solver) is one task depending on its map's.  Results are appended as
    they complete; failures are recorded and the rest go on.

    Parameters
    ----------
    client : distributed.Client
        The cluster.
    maps : sequence of MapTask
        The sky maps.
    settings : BenchSettings
        Solvers and scoring.
    out : path
        Output directory (``results.jsonl``, ``localisations.jsonl``).
    localisation : Localisation, optional
        Options for maps still to localise.
    progress : bool
        A tqdm bar on stderr.
    """
    from distributed import as_completed
    from tqdm import tqdm

    out = Path(out)
    store = ResultStore(out / "results.jsonl")
    loc_log = ResultStore(out / "localisations.jsonl")
    config = study_config(settings)
    config_hash = _digest(config)
    done = {k for k, r in store.records().items() if r.get("ok")}
    localisation = localisation or Localisation()

    futures: dict[Any, tuple[str, Any]] = {}
    executed: list[str] = []
    loc_futures: dict[str, Any] = {}
    for m in maps:
        todo = [s for s in settings.solvers if result_key(m.key, s, config_hash) not in done]
        if not todo:
            continue
        source: Any = m.path
        if m.events is not None and not Path(m.path).exists():
            fut = client.submit(localise, m.events, m.coinc_id, localisation, m.path,
                                key=f"localise-{_digest([m.key], 12)}", pure=False)
            loc_futures[m.key] = fut
            futures[fut] = ("localise", m)
            source = fut
        for s in todo:
            k = result_key(m.key, s, config_hash)
            fut = client.submit(plan_and_score, source, s, settings, key=f"plan-{_digest([k], 16)}", pure=False)
            futures[fut] = ("plan", (m, s, k))
            executed.append(k)

    failed: list[str] = []
    locs: list[dict[str, Any]] = []
    n_plan = len(executed)
    bar = tqdm(total=len(futures), desc="study", unit="task", disable=not progress or not futures, file=sys.stderr)
    try:
        for fut in as_completed(list(futures)):
            kind, what = futures.pop(fut)
            now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
            if kind == "localise":
                rec = dict(kind="result", key=what.key, coinc_id=what.coinc_id, events=what.events, finished=now,
                           options=dataclasses.asdict(localisation))
                if fut.status == "finished":
                    rec.update(ok=True, **fut.result())
                    locs.append(rec)
                else:
                    exc = fut.exception()
                    rec.update(ok=False, error=f"{type(exc).__name__}: {exc}"[:500],
                               traceback=_tb_of_future(fut))
                loc_log.append(rec)
                bar.set_postfix_str(f"localised {Path(what.events).name.split('.')[0]}:{what.coinc_id}")
            else:
                m, s, k = what
                if fut.status == "finished":
                    res = fut.result()
                else:  # the task itself died (its map's localisation failed, a worker was lost ...)
                    exc = fut.exception()
                    res = dict(row=bench._row(m.path, s, status=f"error: {type(exc).__name__}: {exc}"[:300],
                                              valid=False),
                               ok=False, error=f"{type(exc).__name__}: {exc}"[:500], traceback=_tb_of_future(fut),
                               versions=None, task_s=None)
                res["row"]["skymap"] = m.name
                if not res["ok"]:
                    failed.append(k)
                store.append(dict(kind="result", key=k, map=m.key, skymap=m.name, solver=s, finished=now,
                                  config_hash=config_hash, config=config, **res))
                cov = bench._num(res["row"].get("coverage"))
                bar.set_postfix_str(f"{Path(m.name).name} {s}: " + (f"{cov:.3f}" if cov is not None else "failed"))
            bar.update(1)
            fut.release()
    finally:
        bar.close()
        for fut in futures:
            fut.cancel()
    log.info("study: %d (map, solver) task(s) run, %d failed, %d map(s) localised", n_plan, len(failed), len(locs))
    records = store.records()
    rows = []
    for m in maps:
        for s in settings.solvers:
            rec = records.get(result_key(m.key, s, config_hash))
            if rec is not None:
                row = dict(rec["row"])
                row["skymap"] = m.name
                rows.append(row)
    return StudyRun(rows=rows, executed=executed, failed=failed, localisations=locs)


def _tb_of_future(fut: Any) -> str:
    try:
        tb = fut.traceback()
        exc = fut.exception()
        frames = traceback.extract_tb(tb)[-TRACEBACK_FRAMES:] if tb is not None else []
        lines = [f"{Path(f.filename).name}:{f.lineno} in {f.name}: {(f.line or '').strip()}" for f in frames]
        return " | ".join(lines + [f"{type(exc).__name__}: {exc}"])[:2000]
    except Exception:  # pragma: no cover - a traceback that cannot be read is not worth failing over
        return ""


# --------------------------------------------------------------------------- stage (d): tables and figures


def _baselines(solvers: Sequence[str]) -> list[str]:
    return [b for b in ("greedy", "gwemopt", "gwemopt-repaired") if b in solvers]


def similar_length_maps(rows: Sequence[Mapping[str, Any]], a: str, b: str,
                        within: int = bench.SIMILAR_LENGTH) -> set[str]:
    """The paper's similar-length subset: maps where ``a`` and ``b`` plan within ``within`` exposures."""
    out = set()
    for name, sol in bench._by_map(rows).items():
        ra, rb = sol.get(a), sol.get(b)
        if bench._scored(ra) and bench._scored(rb):
            na, nb = bench._num(ra.get("n_exposures")), bench._num(rb.get("n_exposures"))
            if na is not None and nb is not None and abs(na - nb) <= within:
                out.add(name)
    return out


def _pair(solvers: Sequence[str]) -> tuple[str | None, str | None]:
    """(ours, baseline) of the paper's comparison: MUSHROOMS' best solver against gwemopt, else greedy."""
    base = next((s for s in ("gwemopt", "gwemopt-repaired", "greedy") if s in solvers), None)
    ours = next((s for s in ("hybrid", "blocks", "milp", "slots", "greedy") if s in solvers and s != base), None)
    return ours, base


def _table(rows: Sequence[Mapping[str, Any]], names: Sequence[str], baselines: Sequence[str],
           eff_keys: Sequence[str]) -> list[str]:
    head = ["solver", "objective", "maps", "coverage"] + [f"eff. {k}" for k in eff_keys] + ["n_exp", "cov/bound"]
    head += [f"vs {b}: cov W/L/T" for b in baselines] + [f"vs {b}: eff. {k[:4]} W/L/T" for b in baselines
                                                          for k in eff_keys]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in names:
        rs = [r for r in rows if r["solver"] == s and bench._scored(r)]

        def mean(key: str, digits: int = 4) -> str:
            xs = [x for x in (bench._num(r.get(key)) for r in rs) if x is not None]
            return f"{sum(xs) / len(xs):.{digits}f}" if xs else "-"

        cells = [s, bench._objective_of(rs), str(len(rs)), mean("coverage")] + [mean(f"efficiency_{k}") for k in eff_keys]
        cells += [mean("n_exposures", 1), mean("coverage_over_bound")]
        for b in baselines:
            cells.append("-" if b == s else "%d/%d/%d" % bench._wins(rows, s, b, "coverage", bench.TIE_COVERAGE))
        for b in baselines:
            for k in eff_keys:
                cells.append("-" if b == s else "%d/%d/%d" % bench._wins(rows, s, b, f"efficiency_{k}",
                                                                         bench.TIE_EFFICIENCY))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def paper_tables(rows: Sequence[Mapping[str, Any]],
                 eff_keys: Sequence[str] = ("optimistic", "conservative", "nsbh")) -> str:
    """The paper's Tables 2-3 layout (Markdown): all maps, then the similar-length subset.

    Per solver, and for the paper's hybrid best-of(ours, baseline): maps
    scored, mean coverage, mean efficiency per light curve, mean exposures,
    mean coverage over the certified bound, and wins/losses/ties against each
    baseline present (greedy, gwemopt, gwemopt-repaired).  The subset is the
    paper's: maps where ours and the baseline plan within
    :data:`~mushrooms.evaluation.bench.SIMILAR_LENGTH` exposures of each other.
    """
    rows = [dict(r) for r in rows]
    solvers = list(dict.fromkeys(str(r["solver"]) for r in rows))
    ours, base = _pair(solvers)
    extra = bench.best_of(rows, ours, base) if ours and base else []
    names = solvers + ([f"best({ours},{base})"] if extra else [])
    allrows = rows + extra
    baselines = _baselines(solvers)
    n_maps = len(bench._by_map(rows))
    n_failed = sum(1 for r in rows if not bench._scored(r))
    lines = [f"All maps ({n_maps}; {n_failed} (map, solver) result(s) without a plan). "
             "W/L/T: maps won/lost/tied against the baseline (coverage tie <= 1e-4, efficiency tie <= 1e-3).", ""]
    lines += _table(allrows, names, baselines, eff_keys)
    if ours and base:
        subset = similar_length_maps(rows, ours, base)
        lines += ["", f"Similar-length subset ({len(subset)} of {n_maps} maps: |n_exposures({ours}) - "
                      f"n_exposures({base})| <= {bench.SIMILAR_LENGTH}, the paper's section 4.1).", ""]
        lines += _table([r for r in allrows if r["skymap"] in subset], names, baselines, eff_keys)
    return "\n".join(lines)


def _save_histogram(fig: Any, ax: Any, out: Path) -> Path:
    """Finish a histogram of map counts (integer ticks, legend) and write it."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def make_figures(rows: Sequence[Mapping[str, Any]], directory: str | Path) -> list[Path]:
    """The paper's figures (PNG): coverage scatter and efficiency vs 90 % area (all maps and the
    similar-length subset, the bench's :func:`~mushrooms.evaluation.bench.make_plots`), the solve-time
    histogram per solver and the 90 % area histograms of all maps and of the subset."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    directory = Path(directory)
    written = bench.make_plots(rows, directory)
    solvers = list(dict.fromkeys(str(r["solver"]) for r in rows))
    ours, base = _pair(solvers)
    subset = similar_length_maps(rows, ours, base) if ours and base else set()
    if subset:
        written += bench.make_plots([r for r in rows if r["skymap"] in subset], directory / "similar_length")

    times = {s: [x for x in (bench._num(r.get("solve_s")) for r in rows if r["solver"] == s and bench._scored(r))
                 if x is not None and x > 0] for s in solvers}
    times = {s: t for s, t in times.items() if t}
    if times:
        fig, ax = plt.subplots(figsize=(6, 4))
        lo = min(min(t) for t in times.values())
        hi = max(max(t) for t in times.values())
        bins = np.geomspace(lo * 0.9, hi * 1.1, 25)
        for s, t in times.items():
            ax.hist(t, bins=bins, histtype="step", lw=1.5,
                    label=f"{s} (median {np.median(t):.2f} s, mean {np.mean(t):.2f} s)")
        ax.set_xscale("log")
        ax.set_xlabel("solve time per map (s, wall clock)")
        ax.set_ylabel("sky maps")
        ax.set_title(f"solve time, {max(len(t) for t in times.values())} sky maps")
        written.append(_save_histogram(fig, ax, directory / "solve_time_hist.png"))

    area = {name: bench._num(next(iter(sol.values())).get("area90_deg2"))
            for name, sol in bench._by_map(rows).items()}
    area = {k: v for k, v in area.items() if v is not None and v > 0}
    if area and ours and base:
        fig, ax = plt.subplots(figsize=(6, 4))
        bins = np.geomspace(min(area.values()) * 0.9, max(area.values()) * 1.1, 20)
        ax.hist(list(area.values()), bins=bins, alpha=0.5, label=f"all maps ({len(area)})")
        ax.hist([v for k, v in area.items() if k in subset], bins=bins, alpha=0.7,
                label=f"similar length, {ours} vs {base} ({sum(1 for k in area if k in subset)})")
        ax.set_xscale("log")
        ax.set_xlabel("90% credible area (deg$^2$)")
        ax.set_ylabel("sky maps")
        written.append(_save_histogram(fig, ax, directory / "area_hist_similar_length.png"))
    return written


# --------------------------------------------------------------------------- CLI


def _cache_dir(args: Any) -> Path:
    if getattr(args, "cache", None):
        return Path(args.cache)
    base = os.environ.get("MUSHROOMS_CACHE_DIR") or os.environ.get("CACHE_DIRECTORY") or "~/.cache/mushrooms"
    return Path(base).expanduser() / "study"


def main(args: Any) -> int:
    """``mushrooms study``: run the study, write ``results.csv``, ``tables.md``, figures; print the tables.

    Returns
    -------
    int
        0 when every task ran (failed tasks are records, not errors); 2 on bad input.
    """
    from ..scheduler_core.errors import InputError

    settings = bench._load_settings(args)
    cfg = settings.config
    if getattr(cfg, "threads", 1) == 0:  # one thread per worker: HiGHS too
        settings = dataclasses.replace(settings, config=dataclasses.replace(cfg, threads=1))
    settings = dataclasses.replace(settings, legacy_scoring=False)  # the fixed source model only
    if args.limit is not None and args.limit < 1:
        raise InputError(f"--limit must be >= 1, got {args.limit}")
    if not args.scheduler and args.workers < 1:
        raise InputError(f"--workers must be >= 1, got {args.workers}")
    out, cache = Path(args.out), _cache_dir(args)
    options = Localisation()
    maps: list[MapTask] = []
    events: str | None = None
    if args.maps:
        maps = maps_from_directory(args.maps)
    elif args.simulate is not None:
        if args.simulate < 1:
            raise InputError(f"--simulate must be >= 1, got {args.simulate}")
        if args.intrinsic_samples is not None and args.intrinsic_samples < 1:
            raise InputError(f"--intrinsic-samples must be >= 1, got {args.intrinsic_samples}")
        if args.chunk < 1:
            raise InputError(f"--chunk must be >= 1, got {args.chunk}")
        if args.detections is not None and args.detections < 1:
            raise InputError(f"--detections must be >= 1, got {args.detections}")
    else:
        events = args.events or str(DEFAULT_EVENTS)
        if not Path(events).is_file():
            raise InputError(f"no such events file: {events}")
    if args.only_simulate and args.simulate is None:
        raise InputError("--only-simulate goes with --simulate")
    if args.detections is not None and args.simulate is None:
        raise InputError("--detections goes with --simulate (for other inputs use --limit)")
    t0 = time.perf_counter()
    stages: dict[str, float] = {}
    realized: list[dict[str, Any]] = []
    client = open_client(args.workers, args.scheduler, dashboard=args.dashboard)
    try:
        if not maps:
            if args.simulate is not None:
                population = Population(n_injections=args.simulate, seed=args.seed,
                                        intrinsic_samples=args.intrinsic_samples, chunk=args.chunk)
                print(f"simulating {args.simulate} injections (seed {args.seed}, chunks of {args.chunk}"
                      + (f", until {args.detections} coincidences" if args.detections else "")
                      + f") -> {cache / 'populations'}", file=sys.stderr)
                jobs = max(1, sum(client.nthreads().values()))
                try:
                    files, realized = simulate_population(
                        population, cache / "populations", client, detections=args.detections, jobs=jobs,
                        progress=os.environ.get("MUSHROOMS_PROGRESS", "1") != "0")
                except SimulationError as exc:
                    print(f"mushrooms study: simulation failed: {exc}", file=sys.stderr)
                    return 1
                sim_log = ResultStore(out / "realizations.jsonl")
                for rec in realized:
                    sim_log.append(dict(kind="realization", population=dataclasses.asdict(population), **rec))
                stages["simulate_s"] = time.perf_counter() - t0
                if args.only_simulate:
                    n = sum(len(coinc_ids(f)) for f in files)
                    print(f"simulated: {sum(r['injections'] for r in realized)} injection(s) realised in "
                          f"{len(realized)} chunk(s), {len(files)} chunk(s) taken, {n} coincidence(s) in them; "
                          f"CPU {sum(r['cpu_s'] for r in realized):.0f} s; wall {stages['simulate_s']:.0f} s")
                    for f in files:
                        print(f)
                    return 0
            else:
                files = [str(events)]
            for f in files:
                maps += maps_from_events(f, cache, options, coinc_ids(f))
            if not maps:
                raise InputError(f"{', '.join(files)}: no coincidences")
            if args.detections:
                maps = maps[:args.detections]
        if args.limit:
            maps = maps[:args.limit]
        print(f"{len(maps)} map(s) x {len(settings.solvers)} solver(s) on "
              f"{args.scheduler or f'a local cluster of {args.workers} worker(s)'}", file=sys.stderr)
        t1 = time.perf_counter()
        run = run_study(client, maps, settings, out, options,
                        progress=os.environ.get("MUSHROOMS_PROGRESS", "1") != "0")
        stages["localise_plan_score_s"] = time.perf_counter() - t1
    finally:
        client.close()
        cluster = getattr(client, "cluster", None)
        if cluster is not None and not args.scheduler:
            cluster.close()
    bench.write_csv(run.rows, out / "results.csv")
    eff_keys = tuple(settings.lightcurves)
    text = paper_tables(run.rows, eff_keys)
    wall = time.perf_counter() - t0
    cpu = [r["cpu_s"] for r in run.localisations if not r.get("cached")]
    footer = (f"{len(maps)} map(s), solvers {','.join(settings.solvers)}, {settings.n_injections} injections/map; "
              f"this run: {len(run.executed)} (map, solver) task(s), {len(run.failed)} failed, "
              f"{len(cpu)} localisation(s)" + (f" (CPU median {sorted(cpu)[len(cpu) // 2]:.0f} s, "
                                               f"total {sum(cpu):.0f} s)" if cpu else "")
              + (f"; {sum(r['injections'] for r in realized)} injection(s) realised in {len(realized)} chunk(s), "
                 f"{sum(r['coincidences'] for r in realized)} coincidence(s), CPU "
                 f"{sum(r['cpu_s'] for r in realized):.0f} s" if realized else "")
              + f"; wall {wall:.0f} s " + json.dumps({k: round(v, 1) for k, v in stages.items()}))
    (out / "tables.md").write_text(text + "\n\n" + footer + "\n")
    print(text)
    print("\n" + footer)
    if not args.no_figures and run.rows:
        for p in make_figures(run.rows, out / "figures"):
            print(f"figure: {p}")
    return 0
