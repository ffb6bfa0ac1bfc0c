"""Stages (b) and (c) of a study on Dask: plan and score every (map, solver), localising maps first.

Maps still to localise get one localisation task each; each (map, solver)
is one task, depending on its map's: the benchmark's own
:func:`~mushrooms.evaluation.bench.per_map.bench_map` on that map with that
one row (coverage by the independent checker, kilonova efficiencies with the
fixed source model, the certified coverage upper bound).  Every finished
result is appended at once to ``<out>/results.jsonl`` (:mod:`.store`) with
the software versions of the worker that made it and the configuration; a
task that fails is recorded with its error and the last frames of its
traceback, and the others go on.

The engine is Dask distributed: a :class:`distributed.LocalCluster` of
single-threaded worker processes (:func:`open_client`), or any running
scheduler (e.g. one started by dask-jobqueue on a Slurm or HTCondor site).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

from ..bench.compare import scored
from ..bench.per_map import bench_map
from ..bench.rows import make_row, num
from ..bench.run import worker_init
from ..bench.settings import BenchSettings
from ..commit import code_commit
from .localisation import Localisation, MapTask, localise
from .provenance import digest, future_traceback, software_versions, traceback_summary
from .store import ResultStore, result_key, study_config

__all__ = ["plan_and_score", "open_client", "StudyRun", "run_graph"]

log = logging.getLogger(__package__)  # the study's one logger (its records say "mushrooms.evaluation.study")

Record = dict[str, Any]


def plan_and_score(skymap: str | Mapping[str, Any], solver: str, settings: BenchSettings, *after: Any) -> Record:
    """Plan one map with one solver and score the plan (the bench's :func:`~mushrooms.evaluation.bench.bench_map`).

    Parameters
    ----------
    skymap : str or mapping
        Sky map path, or the result of :func:`~.localisation.localise` (its ``path``).
    solver : str
        A row name (:data:`mushrooms.evaluation.bench.SOLVERS`, or ours with a forced objective).
    settings : BenchSettings
        The study's settings (its ``solvers`` are ignored).
    *after
        Results of tasks this one waits for (ignored; on Dask, futures
        passed here order the tasks: gwemopt's repaired row after its raw row).

    Returns
    -------
    dict
        ``row`` (the bench's CSV row), ``ok`` (scored), ``error`` and
        ``traceback`` (a failure: a raised exception, or a row the bench
        could not score), ``versions``, ``task_s`` (wall time, s) and
        ``cpu_s`` (CPU time of this process and of the tools it waited for,
        gwemopt's interpreter included, s) and ``commit`` (the code that
        planned the row, :func:`~mushrooms.evaluation.commit.code_commit`; also
        in the row).
    """
    worker_init()
    path = skymap["path"] if isinstance(skymap, Mapping) else str(skymap)
    t0, c0 = time.perf_counter(), _cpu_s()
    try:
        row = bench_map(path, dataclasses.replace(settings, solvers=(solver,)), raise_errors=True)[0]
    except Exception as exc:  # recorded; the study goes on
        row = make_row(path, solver, status=f"error: {type(exc).__name__}: {exc}"[:300], valid=False,
                       commit=code_commit())
        return dict(row=row, ok=False, error=f"{type(exc).__name__}: {exc}"[:500],
                    traceback=traceback_summary(exc), versions=software_versions(),
                    task_s=round(time.perf_counter() - t0, 3), cpu_s=round(_cpu_s() - c0, 3), commit=code_commit())
    ok = scored(row)
    return dict(row=row, ok=ok, error=None if ok else str(row.get("status")), traceback=None,
                versions=software_versions(), task_s=round(time.perf_counter() - t0, 3),
                cpu_s=round(_cpu_s() - c0, 3), commit=code_commit())


def _cpu_s() -> float:
    """CPU seconds (user + system) of this process and of its finished children so far."""
    import resource

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _with_truth(settings: BenchSettings, m: MapTask) -> BenchSettings:
    """``settings`` with the injected truth of a simulated coincidence (the independent scoring puts its
    kilonovae there); unchanged for an existing map, or an events file that is unreadable (its localisation
    task reports that) or holds no injections."""
    if m.events is None or m.coinc_id is None:
        return settings
    from .population_rows import coinc_injections

    try:
        inj = coinc_injections(m.events).get(int(m.coinc_id))
    except Exception:  # noqa: BLE001 - a missing or broken events file fails in its own localisation task
        return settings
    if inj is None:
        return settings
    return dataclasses.replace(settings, truth=(inj["ra_deg"], inj["dec_deg"], inj["distance_mpc"]))


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
    """What one :func:`run_graph` call did.

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
        :func:`~.localisation.localise` results of this run (CPU and wall time per map).
    """

    rows: list[Record]
    executed: list[str]
    failed: list[str]
    localisations: list[Record]


@dataclass
class _Graph:
    """The tasks of one run: what each future is, and where its result goes."""

    store: ResultStore
    loc_log: ResultStore
    config: dict[str, Any]
    config_hash: str
    localisation: Localisation
    futures: dict[Any, tuple[str, Any]] = field(default_factory=dict)
    executed: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    localisations: list[Record] = field(default_factory=list)

    def submit(self, client: Any, maps: Sequence[MapTask], settings: BenchSettings) -> None:
        """One localisation task per map still to localise, one plan task per (map, solver) not yet done."""
        done = {k for k, r in self.store.records().items() if r.get("ok")}
        for m in maps:
            todo = [s for s in settings.solvers if result_key(m.key, s, self.config_hash) not in done]
            if not todo:
                continue
            source: Any = m.path
            if m.events is not None and not Path(m.path).exists():
                source = client.submit(localise, m.events, m.coinc_id, self.localisation, m.path,
                                       key=f"localise-{digest([m.key], 12)}", pure=False)
                self.futures[source] = ("localise", m)
            submitted: dict[str, Any] = {}
            mine = _with_truth(settings, m)
            for s in todo:
                k = result_key(m.key, s, self.config_hash)
                # gwemopt runs once per map: its repaired row waits for the raw row's run (cached) instead of
                # running gwemopt a second time beside it
                after = [submitted["gwemopt"]] if s == "gwemopt-repaired" and "gwemopt" in submitted else []
                fut = client.submit(plan_and_score, source, s, mine, *after, key=f"plan-{digest([k], 16)}",
                                    pure=False)
                submitted[s] = fut
                self.futures[fut] = ("plan", (m, s, k))
                self.executed.append(k)

    def localised(self, fut: Any, m: MapTask, now: str) -> str:
        """Record a finished localisation task; the progress bar's note."""
        rec = dict(kind="result", key=m.key, coinc_id=m.coinc_id, events=m.events, finished=now,
                   options=dataclasses.asdict(self.localisation))
        if fut.status == "finished":
            rec.update(ok=True, **fut.result())
            self.localisations.append(rec)
        else:
            exc = fut.exception()
            rec.update(ok=False, error=f"{type(exc).__name__}: {exc}"[:500], traceback=future_traceback(fut))
        self.loc_log.append(rec)
        return f"localised {Path(m.events).name.split('.')[0]}:{m.coinc_id}"

    def planned(self, fut: Any, m: MapTask, s: str, k: str, now: str) -> str:
        """Record a finished plan task (or the death of one); the progress bar's note."""
        if fut.status == "finished":
            res = fut.result()
        else:  # the task itself died (its map's localisation failed, a worker was lost ...)
            exc = fut.exception()
            res = dict(row=make_row(m.path, s, status=f"error: {type(exc).__name__}: {exc}"[:300], valid=False),
                       ok=False, error=f"{type(exc).__name__}: {exc}"[:500], traceback=future_traceback(fut),
                       versions=None, task_s=None)
        res["row"]["skymap"] = m.name
        if not res["ok"]:
            self.failed.append(k)
        self.store.append(dict(kind="result", key=k, map=m.key, skymap=m.name, solver=s, finished=now,
                               config_hash=self.config_hash, config=self.config, **res))
        cov = num(res["row"].get("coverage"))
        return f"{Path(m.name).name} {s}: " + (f"{cov:.3f}" if cov is not None else "failed")

    def collect(self, progress: bool) -> None:
        """Record every task as it completes; on the way out, cancel what is left."""
        from distributed import as_completed
        from tqdm import tqdm

        bar = tqdm(total=len(self.futures), desc="study", unit="task", disable=not progress or not self.futures,
                   file=sys.stderr)
        try:
            for fut in as_completed(list(self.futures)):
                kind, what = self.futures.pop(fut)
                now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
                note = self.localised(fut, what, now) if kind == "localise" else self.planned(fut, *what, now)
                bar.set_postfix_str(note)
                bar.update(1)
                fut.release()
        finally:
            bar.close()
            for fut in self.futures:
                fut.cancel()

    def rows(self, maps: Sequence[MapTask], solvers: Sequence[str]) -> list[Record]:
        """The stored row of every (map, solver) of the study, in map then solver order."""
        records = self.store.records()
        rows = []
        for m in maps:
            for s in solvers:
                rec = records.get(result_key(m.key, s, self.config_hash))
                if rec is not None:
                    row = dict(rec["row"])
                    row["skymap"] = m.name
                    rows.append(row)
        return rows


def run_graph(client: Any, maps: Sequence[MapTask], settings: BenchSettings, out: str | Path,
              localisation: Localisation | None = None, progress: bool = False) -> StudyRun:
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
    out = Path(out)
    config = study_config(settings)
    graph = _Graph(store=ResultStore(out / "results.jsonl"), loc_log=ResultStore(out / "localisations.jsonl"),
                   config=config, config_hash=digest(config), localisation=localisation or Localisation())
    graph.submit(client, maps, settings)
    n_plan = len(graph.executed)
    graph.collect(progress)
    log.info("study: %d (map, solver) task(s) run, %d failed, %d map(s) localised", n_plan, len(graph.failed),
             len(graph.localisations))
    return StudyRun(rows=graph.rows(maps, settings.solvers), executed=graph.executed, failed=graph.failed,
                    localisations=graph.localisations)
