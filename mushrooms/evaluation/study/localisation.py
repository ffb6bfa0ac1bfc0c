"""Stage (a) of a study, localised: the sky maps of a study, existing files or coincidences for BAYESTAR.

A coincidence of an events file (``events.xml.gz``; default the packaged O3
BNS population :data:`DEFAULT_EVENTS`: 600 injections, 21 coincidences) is
localised one task per coincidence with ``bayestar-localize-coincs
--coinc-event-id`` (``OMP_NUM_THREADS=1``), each map cached on disk keyed by
(events file hash, coinc id, localisation options), so a planning study
never localises twice.  Or the maps are the files of a directory.
"""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

from ..bench.run import skymaps_in
from .ligo_tools import run_tool
from .population import coinc_ids
from .provenance import digest, sha256_file

__all__ = ["DEFAULT_EVENTS", "Localisation", "MapTask", "localised_path", "localise", "maps_from_directory",
           "maps_from_events"]

#: The O3 BNS population of ``shared/data/skymaps/simulated/bns_o3_pipeline/``: the realised
#: coincidences (21) of its first 600 injections (packaged; see ``data/populations/SOURCES.md``).
DEFAULT_EVENTS = Path(__file__).resolve().parents[2] / "data" / "populations" / "bns_o3" / "events.xml.gz"


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
        return digest(self.arguments())


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
        cpu = run_tool(["bayestar-localize-coincs", str(events), "--coinc-event-id", str(coinc_id),
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
    """The sky maps under a directory, keyed by their bytes (InputError when there is none:
    :func:`~mushrooms.evaluation.bench.run.skymaps_in`)."""
    return [MapTask(key=sha256_file(p)[:24], name=str(p), path=str(p)) for p in skymaps_in(directory)]


def maps_from_events(events: str | Path, cache: str | Path, options: Localisation,
                     ids: Iterable[int] | None = None) -> list[MapTask]:
    """One map per coincidence of an events file (``ids``: a subset), cached under ``cache``."""
    events = str(Path(events).resolve())
    sha = sha256_file(events)
    ids = coinc_ids(events) if ids is None else list(ids)
    out = []
    for cid in ids:
        path = localised_path(cache, sha, cid, options)
        out.append(MapTask(key=f"{sha[:16]}:{cid}:{options.key()}", name=str(path), path=str(path),
                           events=events, coinc_id=cid))
    return out

