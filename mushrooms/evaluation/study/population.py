"""Stage (a) of a study, simulated: a population of BNS mergers made with ligo.skymap's own tools.

``bayestar-sample-model-psd`` → ``bayestar-inject`` → one
``bayestar-realize-coincs`` task per chunk of injections, realised in order
until they hold the coincidences asked for (the O3 BNS recipe of
``shared/data/skymaps/simulated/SOURCES.md``, see :class:`Population` and
:func:`simulate_population`).  Everything is cached on disk under the
population's key; a chunk already realised there (e.g. copied from a
committed run) is taken as it is, and the injections are only made when a
chunk still has to be realised.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

from ...scheduler_core.plan import strict_json
from .defaults import DEFAULT_CHUNK, DEFAULT_SEED
from .ligo_tools import run_tool
from .provenance import digest

__all__ = ["Population", "SimulationError", "inject_population", "split_injections", "realize_chunk",
           "cached_chunk", "chunks_needed", "simulate_population", "coinc_ids", "POLL_S"]

Record = dict[str, Any]


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
    post : str
        A rule applied to each realised chunk before it is cached: ``""`` none,
        ``"o4-real"`` the epochs, per-detector duty cycles and FAR-like
        threshold of :mod:`.o4_real` (seeded like the chunk's realisation).
        Part of the key only when set, so the keys of older populations stand.
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
    chunk: int = DEFAULT_CHUNK
    post: str = ""

    def __post_init__(self) -> None:
        if self.post not in POST_RULES:
            raise ValueError(f"post must be one of {', '.join(map(repr, POST_RULES))}, got {self.post!r}")

    def key(self) -> str:
        """Cache key of the injections (the realisation chunk size is not part of it; ``post`` only when set)."""
        return digest(_keyed(self))

    def chunks(self) -> list[tuple[int, int]]:
        """The realisation chunks: ``(start, stop)`` injection indices, in order."""
        if self.chunk < 1:
            raise ValueError(f"chunk must be >= 1, got {self.chunk}")
        return [(a, min(a + self.chunk, self.n_injections)) for a in range(0, self.n_injections, self.chunk)]


#: Rules a population may apply to its realised chunks (:attr:`Population.post`).
POST_RULES = ("", "o4-real")


def _keyed(population: Population) -> dict[str, Any]:
    """What identifies a population's injections: every field but the chunk size (and an unset ``post``)."""
    d = dataclasses.asdict(population)
    d.pop("chunk")
    if not d["post"]:
        d.pop("post")
    return d


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
    meta = _keyed(population)
    (d / "population.json").write_text(strict_json.dumps(meta, indent=1))
    psd = ["bayestar-sample-model-psd", "-o", "psds.xml"]
    for det, model, scale in population.psd_scales:
        psd += [f"--{det}", model, f"--{det}-scale", str(scale)]
    run_tool(psd, cwd=d)
    if population.intrinsic_samples:
        _write_intrinsic_samples(population, d / "intrinsic_samples.ecsv")
        source = ["--distribution-samples", "intrinsic_samples.ecsv"]
    else:
        source = ["--distribution", population.distribution]
    run_tool(["bayestar-inject", "-l", "error", "--seed", str(population.seed),
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


def _chunk_events(population: Population, population_dir: str | Path, k: int) -> Path:
    """Where chunk ``k``'s events file is cached (``population_dir``: the population's own directory)."""
    return Path(population_dir) / f"realized-{population.chunk}" / f"events-{k:04d}.xml.gz"


def cached_chunk(population: Population, directory: str | Path, k: int) -> dict[str, Any] | None:
    """Chunk ``k``'s record when its events file is already in the cache under ``directory`` (else None);
    the injections are not needed for it."""
    return _cached_record(population, _chunk_events(population, Path(directory) / population.key(), k), k)


def _cached_record(population: Population, events: Path, k: int) -> dict[str, Any] | None:
    """The record of chunk ``k`` realised as ``events`` (None when that file does not exist)."""
    if not events.exists():
        return None
    start, stop = population.chunks()[k]
    return dict(chunk=k, events=str(events), injections=stop - start, coincidences=len(coinc_ids(events)),
                cpu_s=0.0, wall_s=0.0, cached=True)


def realize_chunk(population: Population, injections: str, k: int) -> dict[str, Any]:
    """Realise chunk ``k`` of a population's injections (``bayestar-realize-coincs``; cached).

    Returns
    -------
    dict
        ``chunk``, ``events`` (the chunk's ``events.xml.gz``), ``injections``
        (in the chunk), ``coincidences``, ``cpu_s``, ``wall_s``, ``cached``.
    """
    start, stop = population.chunks()[k]
    events = _chunk_events(population, Path(injections).parent, k)
    cached = _cached_record(population, events, k)
    if cached is not None:
        return cached
    d = events.parent
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=d, prefix=f".{k:04d}-") as tmp:
        part = Path(tmp) / "injections.xml"
        split_injections(injections, start, stop, part)
        cpu = run_tool(["bayestar-realize-coincs", "--seed", str(population.seed + 1 + k), "-j", "1", "-l", "error",
                         "-o", "events.xml.gz", "injections.xml", "--reference-psd",
                         str(Path(injections).parent / "psds.xml"),
                         "--snr-threshold", "1", "--net-snr-threshold", str(population.net_snr_threshold),
                         "--min-triggers", "1", "--duty-cycle", str(population.duty_cycle), "--keep-subthreshold",
                         "--measurement-error", "gaussian-noise", "--detector",
                         *[det for det, _, _ in population.psd_scales]], cwd=tmp, omp_threads=1)
        if population.post == "o4-real":  # the epochs, duty cycles and FAR-like threshold of O4 (o4_real.py)
            from .o4_real import apply_o4_real

            apply_o4_real(str(Path(tmp) / "events.xml.gz"), population.seed + 1 + k)
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


def _write_intrinsic_samples(population: Population, path: Path) -> None:
    """N points of the population's mass and spin distribution, seeded (``bns_astro``: bayestar-inject's own
    constants; :data:`~.mass_models.PDB_DISTRIBUTION`: the O4 recipe's PDB model, :mod:`.mass_models`)."""
    import numpy as np
    from astropy.table import Table

    from .mass_models import PDB_DISTRIBUTION, sample_pdb_binaries

    rng = np.random.default_rng(population.seed)
    n = int(population.intrinsic_samples or 0)
    if population.distribution == PDB_DISTRIBUTION:
        Table(sample_pdb_binaries(rng, n)).write(path, format="ascii.ecsv", overwrite=True)
        return
    if population.distribution != "bns_astro":
        raise ValueError(f"intrinsic_samples is implemented for bns_astro and {PDB_DISTRIBUTION}, "
                         f"not {population.distribution}")
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


def simulate_population(population: Population, directory: str | Path, client: Any = None,
                        detections: int | None = None, jobs: int = 1,
                        progress: bool = False) -> tuple[list[str], list[Record]]:
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

    Raises
    ------
    SimulationError
        A tool failed (injecting, or realising a chunk).
    """
    n_chunks = len(population.chunks())
    if client is None:
        records = _simulate_here(population, directory, detections, jobs)
    else:
        records = _simulate_on_cluster(population, directory, client, detections, jobs, progress)
    counts = {i: r["coincidences"] for i, r in records.items()}
    used = chunks_needed(counts, n_chunks, detections) or n_chunks
    used = min(used, len(records))
    chosen = [records[k] for k in range(used) if k in records]
    return [r["events"] for r in chosen], [records[k] for k in sorted(records)]


def _simulate_here(population: Population, directory: str | Path, detections: int | None,
                   jobs: int) -> dict[int, Record]:
    """Realise the chunks in order in this process until they hold ``detections`` (cached chunks taken as they
    are; the injections made before the first chunk that is not)."""
    n_chunks = len(population.chunks())
    injections: str | None = None
    records: dict[int, Record] = {}
    for k in range(n_chunks):
        rec = cached_chunk(population, directory, k)
        if rec is None and injections is None:
            try:
                injections = inject_population(population, directory, jobs)
            except Exception as exc:
                raise SimulationError(f"injecting: {type(exc).__name__}: {exc}") from exc
        try:
            records[k] = rec or realize_chunk(population, str(injections), k)
        except Exception as exc:
            raise SimulationError(f"realising chunk {k}: {type(exc).__name__}: {exc}") from exc
        if chunks_needed({i: r["coincidences"] for i, r in records.items()}, n_chunks, detections) is not None:
            break
    return records


def _simulate_on_cluster(population: Population, directory: str | Path, client: Any, detections: int | None,
                         jobs: int, progress: bool) -> dict[int, Record]:
    """Take the cached chunks; inject as one task once a chunk must be realised, then keep as many chunk tasks
    in flight as the cluster has threads."""
    from tqdm import tqdm

    def injections() -> str:
        inject = client.submit(inject_population, population, str(directory), jobs,
                               key=f"inject-{population.key()}", pure=False)
        try:
            return _result(inject)
        except Exception as exc:
            raise SimulationError(f"injecting: {type(exc).__name__}: {exc}") from exc

    chunks = _ChunkQueue(population, directory, injections, client, detections)
    bar = tqdm(total=chunks.n_chunks, desc="realise", unit="chunk", disable=not progress, file=sys.stderr)
    try:
        while chunks.submit():
            for rec in chunks.finished():
                bar.update(1)
                bar.set_postfix_str(f"{sum(r['coincidences'] for r in chunks.records.values())} coincidences")
    finally:
        bar.close()
        chunks.cancel()
    return chunks.records


class _ChunkQueue:
    """The realisation tasks of one population on a cluster: submitted in chunk order, collected as they end."""

    def __init__(self, population: Population, directory: str | Path, injections: Callable[[], str], client: Any,
                 detections: int | None) -> None:
        self.population, self.directory, self.client, self.detections = population, directory, client, detections
        self.make_injections, self.injections = injections, ""
        self.n_chunks = len(population.chunks())
        self.slots = max(1, sum(client.nthreads().values()))
        self.records: dict[int, Record] = {}
        self.done: list[Record] = []
        self.next = 0
        self.inflight: list[Any] = []

    def submit(self) -> bool:
        """Fill the free slots while more coincidences may be needed (cached chunks taken at once); False when
        nothing is left in flight or to report."""
        p = self.population
        found = sum(r["coincidences"] for r in self.records.values())  # of chunks < next: a lower bound
        while (self.next < self.n_chunks and len(self.inflight) < self.slots
               and (self.detections is None or found < self.detections)):
            cached = cached_chunk(p, self.directory, self.next)
            if cached is not None:  # taken as it is, without a task (and without the injections)
                self.records[self.next] = cached
                self.done.append(cached)
                found += cached["coincidences"]
                self.next += 1
                continue
            self.injections = self.injections or self.make_injections()
            self.inflight.append(self.client.submit(realize_chunk, p, self.injections, self.next,
                                                    key=f"realize-{p.key()}-{p.chunk}-{self.next}", pure=False))
            self.next += 1
        return bool(self.inflight) or bool(self.done)

    def finished(self) -> list[Record]:
        """The records of the tasks done (and the cached chunks taken) since the last look (after a short sleep
        when none is)."""
        out, self.done = self.done, []
        done = [f for f in self.inflight if f.done()]
        if not done:
            if not out:
                time.sleep(POLL_S)  # polled, not blocked in the client: Ctrl-C reaches us
            return out
        for fut in done:
            self.inflight.remove(fut)
            if fut.status != "finished":
                raise SimulationError(f"realising {fut.key}: {type(fut.exception()).__name__}: {fut.exception()}")
            rec = fut.result()
            self.records[rec["chunk"]] = rec
            out.append(rec)
            fut.release()
        return out

    def cancel(self) -> None:
        """Cancel what is still in flight."""
        for fut in self.inflight:
            fut.cancel()
