"""Many sky maps benchmarked: the maps of a directory, ``jobs`` at a time, the CSV kept up to date.

:func:`run_bench` is the benchmark as a library function: plain
:class:`~.settings.BenchSettings` and a list of map files in, rows out.
``mushrooms bench`` (:mod:`mushrooms.tool.bench`) parses the command line,
calls it, writes the CSV and prints the summary.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

from .per_map import bench_map
from .rows import make_row, write_csv
from .settings import BenchSettings

__all__ = ["find_skymaps", "skymaps_in", "run_bench", "worker_init", "failed_rows"]

Row = dict[str, Any]


def find_skymaps(directory: str | Path) -> list[Path]:
    """Sky map files under a directory (recursive, sorted): ``*.fits``, ``*.fits.gz``."""
    root = Path(directory)
    files = [p for p in root.rglob("*") if p.is_file() and (p.name.endswith(".fits") or p.name.endswith(".fits.gz"))]
    return sorted(files)


def skymaps_in(directory: str | Path) -> list[Path]:
    """:func:`find_skymaps` of a command's input directory; InputError when it is missing or has none."""
    from ...scheduler_core.errors import InputError

    root = Path(directory)
    if not root.is_dir():
        raise InputError(f"not a directory: {root}")
    paths = find_skymaps(root)
    if not paths:
        raise InputError(f"no sky maps (*.fits, *.fits.gz) under {root}")
    return paths


def failed_rows(path: str, settings: BenchSettings, why: str) -> list[Row]:
    """One row per solver of a map whose benchmark itself failed (``why``: the status)."""
    return [make_row(path, s, status=why[:300], valid=False) for s in settings.solvers]


def _bench_map_safe(path: str, settings: BenchSettings) -> list[Row]:
    try:
        return bench_map(path, settings)
    except Exception as exc:  # last resort inside a worker
        return failed_rows(path, settings, f"error: {type(exc).__name__}: {exc}")


def worker_init() -> None:
    """Set up a process that plans: no IERS downloads, warnings and worse only."""
    from astropy.utils import iers

    iers.conf.auto_download = False
    logging.getLogger().setLevel(logging.WARNING)


def run_bench(settings: BenchSettings, maps: Sequence[str | Path], jobs: int = 1,
              output: str | Path | None = None, progress: bool = False) -> list[Row]:
    """Benchmark many maps, ``jobs`` at a time in separate processes.

    Parameters
    ----------
    settings : BenchSettings
        Rows, planning configuration and ``[bench]`` scoring.
    maps : sequence of path
        Sky map files (:func:`skymaps_in` of a directory).
    jobs : int
        Parallel worker processes (1 = in this process).
    output : path, optional
        CSV rewritten after every finished map (an interrupted run keeps
        what it measured).
    progress : bool
        Show a tqdm progress bar on stderr.

    Returns
    -------
    list of dict
        Rows in the order of ``maps`` then ``settings.solvers``.
    """
    from tqdm import tqdm

    done: dict[str, list[Row]] = {}
    order = [str(p) for p in maps]
    bar = tqdm(total=len(order), desc="bench", unit="map", disable=not progress, file=sys.stderr)

    def finish(p: str, rows: list[Row]) -> None:
        done[p] = rows
        bar.update(1)
        best = max((r for r in rows if isinstance(r.get("coverage"), float)), key=lambda r: r["coverage"], default=None)
        bar.set_postfix_str(f"{Path(p).name}: best {best['solver']} {best['coverage']:.3f}" if best else Path(p).name)
        if output is not None:
            write_csv([r for q in order if q in done for r in done[q]], output)

    try:
        if jobs <= 1:
            worker_init()
            for p in order:
                finish(p, _bench_map_safe(p, settings))
        else:
            _in_processes(order, settings, jobs, finish)
    finally:
        bar.close()
    return [r for p in order if p in done for r in done[p]]


def _in_processes(order: Sequence[str], settings: BenchSettings, jobs: int,
                  finish: Callable[[str, list[Row]], None]) -> None:
    """Benchmark the maps in ``jobs`` spawned processes, handing each map's rows to ``finish`` as it ends."""
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=worker_init) as pool:
        futures = {pool.submit(_bench_map_safe, p, settings): p for p in order}
        for fut in cf.as_completed(futures):
            p = futures[fut]
            try:
                rows = fut.result()
            except Exception as exc:  # worker died
                rows = failed_rows(p, settings, f"error: worker: {type(exc).__name__}: {exc}")
            finish(p, rows)
