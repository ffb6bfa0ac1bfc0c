"""``mushrooms bench``: every scheduler on a directory of sky maps, judged by numbers.

For each sky map (``*.fits``, ``*.fits.gz`` found recursively) the problem is
prepared once (same horizon, fields, footprints and windows for every
solver), each requested scheduler runs (``greedy``, ``slots``, ``blocks``
(alias ``milp``), ``hybrid`` through
:func:`~mushrooms.scheduler_core.planner.optimise`, exactly as ``make_plan``
publishes under the configuration given, its ``objective`` included;
``<solver>-coverage`` / ``<solver>-detection`` force one objective, and the
CSV column ``objective`` says which each row used; ``gwemopt`` through
:mod:`~mushrooms.evaluation.gwemopt_baseline`, and ``gwemopt-repaired``:
the same gwemopt schedule with every rule-breaking exposure removed by
:func:`~mushrooms.evaluation.gwemopt_baseline.repair_observations`), every plan goes
through the independent plan checker, and the detection efficiency of each
plan is computed with the SAME injections (seeded from the map's hash) for
three kilonova models (optimistic and conservative BNS, NSBH).

Scoring uses the source model the scheduler shares
(:mod:`~mushrooms.scheduler_core.source.kilonova`: light curves alive from the
merger on; :mod:`~mushrooms.scheduler_core.source.depth`: each exposure's limit
from its airmass, Moon and twilight).  Every difference between two plans of
one map is paired (same injections) and reported with its Monte Carlo error:
``efficiency_<lc>_diff`` / ``_differr`` against the reference solver (the
first one listed), and, with ``legacy_scoring``, the first release's score of
the same plan (``efficiency_<lc>_v1``: flat 300 s limits, light curve dark
before 0.202 d) with the paired change ``efficiency_<lc>_v1diff`` /
``_v1differr``.

One CSV row per (sky map, solver); a summary table on stdout; optional plots.
Settings beyond the command line come from an optional ``[bench]`` table in
the ``--config`` file (see :class:`BenchSettings`).
"""

from __future__ import annotations

import concurrent.futures as cf
import csv
import dataclasses
import logging
import math
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..scheduler_core.ranges import Range, check_table, check_value, setting
from ..scheduler_core.solvers_registry import SOLVER_NAMES

__all__ = [
    "COLUMNS",
    "SOLVERS",
    "row_solver",
    "BenchSettings",
    "find_skymaps",
    "bench_map",
    "run_bench",
    "summarize",
    "write_csv",
    "read_csv",
    "make_plots",
    "main",
]

log = logging.getLogger(__name__)

#: Our schedulers (the registry's, :mod:`~mushrooms.scheduler_core.solvers_registry`); the others are gwemopt's rows.
OURS = SOLVER_NAMES
SOLVERS = OURS + ("gwemopt", "gwemopt-repaired")
#: Row names of our schedulers: a plain ``<solver>`` row is what ``make_plan`` publishes under the
#: configuration given (:func:`~mushrooms.scheduler_core.planner.optimise`, ``config.objective``
#: included: under the default ``objective = "detection"`` the scheduler, then the detection stage);
#: ``<solver>-coverage`` and ``<solver>-detection`` force that objective (``-detection`` rows get
#: ``detection_extra_s``).  ``greedy`` is a coverage heuristic under either objective.
OBJECTIVE_SUFFIXES = {"-coverage": "coverage", "-detection": "detection"}
#: What the rows mean; part of the study's result keys, so rows made under older names are not reused
#: (1: plain rows were the coverage scheduler whatever the objective; 2: issue 24).
ROW_NAMES_VERSION = 2

#: CSV columns, in order (the first nine are the issue's required ones).
COLUMNS = (
    "skymap", "solver", "coverage", "efficiency_optimistic", "efficiency_conservative",
    "n_exposures", "runtime_s", "status", "valid",
    "coverage_reported", "n_fields", "schedule_length_s", "first_exposure_s", "mip_gap",
    "prepare_s", "solve_s", "solver_detail", "n_problems", "first_problem",
    "area90_deg2", "distmean_mpc", "n_injections", "distance_source", "start", "note",
    "bound", "coverage_over_bound",
    "expected_detections",
    "detection_stage",
    "objective",
)

#: Coverage differences at or below this count as a tie (absolute probability).
TIE_COVERAGE = 1e-4
#: Efficiency differences at or below this count as a tie.
TIE_EFFICIENCY = 1e-3
#: The paper's "similar schedule length" subset: exposure counts within this of gwemopt's.
SIMILAR_LENGTH = 6


#: ``[bench] maglim`` values: AB magnitudes a 300 s ZTF exposure may reach (21.7 in g and r).
MAGLIM_RANGE = Range(10, 30, "mag")


@dataclass(frozen=True)
class BenchSettings:
    """Everything one benchmark run needs (picklable, sent to worker processes).

    Attributes
    ----------
    config : PlanningConfig
        Planning parameters shared by all solvers.
    solvers : tuple of str
        Subset of :data:`SOLVERS`.
    start_iso : str or None
        One horizon start for all maps (ISO UTC); None = each map's event time.
    n_injections : int
        Kilonova injections per map.
    lightcurves : mapping
        Column suffix -> packaged light-curve name or file path; the CSV has
        ``efficiency_<suffix>`` for each (``optimistic`` and ``conservative``
        by default).
    maglim : mapping
        Limiting magnitude per filter for a 300 s exposure (AB).
    fixed_distance_mpc : float or None
        Distance for maps without distance layers; None = no efficiency there.
    gwemopt_python : str or None
        gwemopt's interpreter (else ``$MUSHROOMS_GWEMOPT_PYTHON``).
    gwemopt_timeout_s : float
        Time limit of one gwemopt run (s).
    gwemopt_cache_dir : str or None
        Directory of cached raw gwemopt schedules (keyed on the sky map's
        bytes and the options passed; format in
        :mod:`~mushrooms.evaluation.gwemopt_baseline`); None = no cache.
    gwemopt_cache_only : bool
        With a cache: never run gwemopt, a map not in the cache gets the
        row status ``not_cached`` (score cached schedules quickly).
    legacy_scoring : bool
        Also score every plan as the first release did (``efficiency_<lc>_v1``).
    reference_solver : str or None
        Paired efficiency differences are against this solver (default: the
        first of ``solvers``).
    detection_extra_s : float
        Budget added for ``<solver>-detection`` rows (s): 0 = they run the
        configuration as it is (``time_limit_s`` split between the coverage
        scheduler and the detection stage); > 0 = they run it with
        ``time_limit_s`` raised by this much and ``detection_time_limit_s``
        set to it, so the coverage scheduler keeps the ``-coverage`` rows'
        whole budget.  Plain rows never get it (they are what is published).
    """

    config: Any
    solvers: tuple[str, ...] = ("greedy", "slots", "blocks", "hybrid")
    start_iso: str | None = None
    n_injections: int = 10_000
    lightcurves: Mapping[str, str] = field(default_factory=lambda: {
        "optimistic": "optimistic", "conservative": "conservative", "nsbh": "nsbh"})
    maglim: Mapping[str, float] = field(default_factory=lambda: {"g": 21.7, "r": 21.7, "i": 21.2})
    fixed_distance_mpc: float | None = setting(None, 1, 20_000, "Mpc", why="unset: no efficiency without distance layers")
    gwemopt_python: str | None = None
    gwemopt_timeout_s: float = setting(1800.0, 1, 86400, "s")
    gwemopt_cache_dir: str | None = None
    gwemopt_cache_only: bool = False
    legacy_scoring: bool = True
    reference_solver: str | None = None
    detection_extra_s: float = setting(0.0, 0, 3600, "s")

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], **base: Any) -> "BenchSettings":
        """Build from a ``[bench]`` table plus keyword arguments (CLI values win)."""
        known = {f.name for f in dataclasses.fields(cls)} - {"config", "solvers", "start_iso", "n_injections"}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown [bench] key(s): {', '.join(unknown)}")
        check_table(cls, values, "bench")
        for band, mag in dict(values.get("maglim", {})).items():
            check_value("bench", f"maglim.{band}", mag, MAGLIM_RANGE)
        kw = dict(values)
        kw.update(base)
        return cls(**kw)


def find_skymaps(directory: str | Path) -> list[Path]:
    """Sky map files under a directory (recursive, sorted): ``*.fits``, ``*.fits.gz``."""
    root = Path(directory)
    files = [p for p in root.rglob("*") if p.is_file() and (p.name.endswith(".fits") or p.name.endswith(".fits.gz"))]
    return sorted(files)


def skymaps_in(directory: str | Path) -> list[Path]:
    """:func:`find_skymaps` of a command's input directory; InputError when it is missing or has none."""
    from ..scheduler_core.errors import InputError

    root = Path(directory)
    if not root.is_dir():
        raise InputError(f"not a directory: {root}")
    paths = find_skymaps(root)
    if not paths:
        raise InputError(f"no sky maps (*.fits, *.fits.gz) under {root}")
    return paths


# --------------------------------------------------------------------------- per map


def row_solver(name: str) -> tuple[str, str | None]:
    """``(scheduler, objective)`` of a row name: ``hybrid-coverage`` -> ``("hybrid", "coverage")``.

    The objective is None for a plain name (the configuration's) and for
    gwemopt's rows.
    """
    for suffix, objective in OBJECTIVE_SUFFIXES.items():
        if name.endswith(suffix) and name[:-len(suffix)] in OURS:
            return name[:-len(suffix)], objective
    return name, None


def is_row_name(name: str) -> bool:
    """A solver name ``mushrooms bench --solvers`` accepts."""
    return name in SOLVERS or row_solver(name)[1] is not None


def _row(skymap: str, solver: str, **values: Any) -> dict[str, Any]:
    row = {c: "" for c in COLUMNS}
    row.update(skymap=skymap, solver=solver)
    row.update({k: v for k, v in values.items() if k in row or k.startswith("efficiency_")})
    return row


def _fmt(x: Any, digits: int = 6) -> Any:
    if x is None:
        return ""
    if isinstance(x, float):
        return "" if not math.isfinite(x) else round(x, digits)
    return x


def _plan_from_result(result: Any, problem: Any, skymap: Any, solver: str) -> Any:
    """A Plan from a ScheduleResult, as make_plan builds it but without raising on the checker."""
    from ..scheduler_core.planner import build_plan

    return build_plan(problem, result, skymap, solver)


def _score(plan: Any, skymap: Any, settings: BenchSettings, footprints: Any, injections: Any,
           lightcurves: Mapping[str, Any], merger_time: Any) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Checker verdict, coverage and efficiencies of one plan, and its detections per light curve."""
    from ..scheduler_core.plan.checker import check_plan
    from ..scheduler_core.source.depth import ZTF_DEPTH
    from .efficiency import detected, paired_difference
    from ..scheduler_core.source.kilonova import Kilonova

    out: dict[str, Any] = {}
    hits: dict[str, np.ndarray] = {}
    report = check_plan(plan, skymap, settings.config)
    obs = plan.observations
    out.update(
        coverage=_fmt(float(report.coverage)),
        coverage_reported=_fmt(float(plan.metrics.coverage)),
        valid=bool(report.ok),
        n_problems=len(report.problems),
        first_problem=(report.problems[0][:200] if report.problems else ""),
        n_exposures=len(obs),
        n_fields=len({o.field_id for o in obs}),
        schedule_length_s=_fmt(float(obs[-1].end - obs[0].start), 1) if obs else 0.0,
        first_exposure_s=_fmt(float(obs[0].start), 1) if obs else "",
        expected_detections=_fmt(getattr(plan.metrics, "expected_detections", None)),
    )
    for key, lc in lightcurves.items():
        if injections is None or merger_time is None:
            out[f"efficiency_{key}"] = ""
            continue
        h = detected(plan, Kilonova(lc), footprints, injections, merger_time, ZTF_DEPTH)
        hits[key] = h
        out[f"efficiency_{key}"] = _fmt(float(h.mean()))
        if settings.legacy_scoring:
            h1 = detected(plan, lc, footprints, injections, merger_time, settings.maglim)
            d, e = paired_difference(h, h1)
            out.update({f"efficiency_{key}_v1": _fmt(float(h1.mean())), f"efficiency_{key}_v1diff": _fmt(d),
                        f"efficiency_{key}_v1differr": _fmt(e)})
    return out, hits


def _pair_with_reference(rows: list[dict[str, Any]], hits: Mapping[str, Mapping[str, np.ndarray]],
                         reference: str) -> None:
    """Add ``efficiency_<lc>_diff`` / ``_differr`` (paired, vs ``reference``) to each row in place."""
    from .efficiency import paired_difference

    ref = hits.get(reference)
    if not ref:
        return
    for row in rows:
        mine = hits.get(str(row["solver"]))
        if not mine or row["solver"] == reference:
            continue
        for key, h in mine.items():
            if key in ref:
                d, e = paired_difference(h, ref[key])
                row[f"efficiency_{key}_diff"] = _fmt(d)
                row[f"efficiency_{key}_differr"] = _fmt(e)


def bench_map(path: str | Path, settings: BenchSettings, raise_errors: bool = False) -> list[dict[str, Any]]:
    """Benchmark every requested solver on one sky map.

    Parameters
    ----------
    path : str or pathlib.Path
        Sky map file.
    settings : BenchSettings
        Solvers, configuration and efficiency settings.
    raise_errors : bool
        Let an unreadable map or a failing solver raise (with its traceback,
        for ``mushrooms study``) instead of becoming a row.

    Returns
    -------
    list of dict
        One row (keys :data:`COLUMNS`) per solver; failures become rows
        with a ``status`` saying why.
    """
    from astropy.time import Time

    from .efficiency import draw_injections
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from ..scheduler_core.schedulers.bound import coverage_upper_bound
    from .gwemopt_baseline import gwemopt_plan, repair_observations, run_gwemopt
    from ..scheduler_core.source.lightcurves import load_lightcurve
    from ..scheduler_core.plan.document import parse_time
    from ..scheduler_core.planner import optimise
    from ..scheduler_core.prepare import prepare_problem
    from ..scheduler_core.sky.skymap import read_skymap

    name = str(path)
    cfg = settings.config
    try:
        skymap = read_skymap(path, nside=cfg.nside)
    except InputError as exc:
        if raise_errors:
            raise
        return [_row(name, s, status=f"skymap_error: {exc}", valid=False) for s in settings.solvers]
    if settings.start_iso:
        start = parse_time(settings.start_iso)
    elif skymap.event_time is not None:
        start = Time(skymap.event_time, scale="utc")
    else:
        return [_row(name, s, status="no_start: map has no event time; give --start", valid=False)
                for s in settings.solvers]
    merger = skymap.event_time if skymap.event_time is not None else start
    common = dict(area90_deg2=_fmt(skymap.credible_area(0.9), 2),
                  distmean_mpc=_fmt(skymap.distmean, 2) if skymap.distmean is not None else "",
                  start=start.isot + "Z")
    notes = []
    if skymap.event_time is None:
        notes.append("no event time: merger taken at the horizon start")

    lightcurves = {k: load_lightcurve(v) for k, v in settings.lightcurves.items()}
    injections = draw_injections(skymap, settings.n_injections, fixed_distance_mpc=settings.fixed_distance_mpc)
    if injections is None:
        notes.append("no distance layers: efficiency skipped (set [bench] fixed_distance_mpc)")
    else:
        common.update(n_injections=len(injections), distance_source=injections.distance_source)
    footprints = field_footprints(load_ztf_fields(), cfg.nside)
    note = "; ".join(notes)

    rows: list[dict[str, Any]] = []
    hits: dict[str, dict[str, np.ndarray]] = {}
    problem, prepare_s, prep_error = None, 0.0, ""
    t0 = time.perf_counter()
    try:  # every row needs it: ours to plan, gwemopt's for the repair and the bound
        problem = prepare_problem(skymap, cfg, start)
    except Exception as exc:  # reported per solver
        if raise_errors:
            raise
        prep_error = f"prepare_error: {type(exc).__name__}: {exc}"
    prepare_s = time.perf_counter() - t0
    bound = coverage_upper_bound(problem).value if problem is not None else None
    if bound is not None:
        common.update(bound=_fmt(bound))

    def with_bound(scores: dict[str, Any]) -> dict[str, Any]:
        cov = _num(scores.get("coverage"))
        if bound is not None and cov is not None and bound > 0:
            scores["coverage_over_bound"] = _fmt(cov / bound, 4)
        return scores

    gw_run = None
    for solver in settings.solvers:
        try:
            if solver in ("gwemopt", "gwemopt-repaired"):
                if gw_run is None:
                    gw_run = run_gwemopt(path, start, cfg, python=settings.gwemopt_python,
                                         timeout_s=settings.gwemopt_timeout_s, cache_dir=settings.gwemopt_cache_dir,
                                         cache_only=settings.gwemopt_cache_only)
                run = gw_run
                if run.status != "ok":
                    rows.append(_row(name, solver, status=run.status, valid=False, runtime_s=_fmt(run.runtime_s, 3),
                                     note="; ".join(filter(None, [note, run.message])), **common))
                    continue
                detail = "gwemopt greedy --doChipGaps" + (" (cached)" if run.message == "cached" else "")
                extra_note = ""
                if solver == "gwemopt-repaired":
                    if problem is None:
                        rows.append(_row(name, solver, status=prep_error or "prepare_error", valid=False,
                                         note=note, **common))
                        continue
                    fixed = repair_observations(run.observations, problem)
                    run = dataclasses.replace(run, observations=fixed.observations)
                    detail += "; repaired"
                    extra_note = "repair: " + ", ".join(f"{k} {v}" for k, v in fixed.counts.items() if v)
                ids = {o.field_id for o in run.observations}
                cov = footprints.coverage(ids, skymap.prob) if ids else 0.0
                plan = gwemopt_plan(run, start, cfg, skymap.sha256, cov)
                if solver == "gwemopt-repaired":
                    plan = dataclasses.replace(plan, metrics=dataclasses.replace(plan.metrics, solver=solver))
                scores, hits[solver] = _score(plan, skymap, settings, footprints, injections, lightcurves, merger)
                scores = with_bound(scores)
                rows.append(_row(name, solver, status=run.status, runtime_s=_fmt(run.runtime_s, 3),
                                 solve_s=_fmt(run.runtime_s, 3), solver_detail=detail, objective="coverage",
                                 note="; ".join(filter(None, [note, extra_note])), **scores, **common))
                continue
            if problem is None:
                rows.append(_row(name, solver, status=prep_error or "prepare_error", valid=False, note=note, **common))
                continue
            base, forced = row_solver(solver)
            rcfg = cfg if forced is None else dataclasses.replace(cfg, objective=forced)
            if forced == "detection" and settings.detection_extra_s > 0:
                rcfg = dataclasses.replace(rcfg, time_limit_s=cfg.time_limit_s + settings.detection_extra_s,
                                           detection_time_limit_s=settings.detection_extra_s)
            objective = "coverage" if base == "greedy" else rcfg.objective
            planned = problem if rcfg == cfg else dataclasses.replace(problem, config=rcfg)
            t0 = time.perf_counter()
            try:  # the whole optimisation of make_plan (the scheduler, then the detection stage if asked)
                result = optimise(planned, skymap, base)
                solve_s = time.perf_counter() - t0
            except ImportError as exc:
                rows.append(_row(name, solver, status="unavailable", valid=False, note=f"{exc}", **common))
                continue
            stage = ""
            if objective == "detection" and result.detection is not None:
                d = result.detection
                solved = [g for g in d.grids if "expected_detections" in g]
                stage = (f"{d.choice}; budget {d.budget_s} s, "
                         f"took {d.runtime_s} s; {len(solved)} grid(s) solved, "
                         f"{sum(not g['above_floor'] for g in solved)} below the floor")
            plan = _plan_from_result(result, planned, skymap, base)
            scores, hits[solver] = _score(plan, skymap, settings, footprints, injections, lightcurves, merger)
            scores = with_bound(scores)
            rows.append(_row(
                name, solver, status=result.status, mip_gap=_fmt(result.mip_gap),
                runtime_s=_fmt(prepare_s + solve_s, 3), prepare_s=_fmt(prepare_s, 3), solve_s=_fmt(solve_s, 3),
                solver_detail=result.solver, note=note, detection_stage=stage, objective=objective,
                **scores, **common))
        except Exception as exc:  # one broken solver must not stop the benchmark
            if raise_errors:
                raise
            log.exception("%s on %s failed", solver, name)
            rows.append(_row(name, solver, status=f"error: {type(exc).__name__}: {exc}"[:300], valid=False,
                             note=note, **common))
    _pair_with_reference(rows, hits, settings.reference_solver or settings.solvers[0])
    return rows


def _bench_map_safe(path: str, settings: BenchSettings) -> list[dict[str, Any]]:
    try:
        return bench_map(path, settings)
    except Exception as exc:  # last resort inside a worker
        return [_row(path, s, status=f"error: {type(exc).__name__}: {exc}"[:300], valid=False)
                for s in settings.solvers]


def _worker_init() -> None:
    from astropy.utils import iers

    iers.conf.auto_download = False
    logging.getLogger().setLevel(logging.WARNING)


def run_bench(paths: Sequence[str | Path], settings: BenchSettings, jobs: int = 1,
              output: str | Path | None = None, progress: bool = True) -> list[dict[str, Any]]:
    """Benchmark many maps, ``jobs`` at a time in separate processes.

    Parameters
    ----------
    paths : sequence of path
        Sky map files.
    settings : BenchSettings
        Shared settings.
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
        Rows in the order of ``paths`` then ``settings.solvers``.
    """
    from tqdm import tqdm

    done: dict[str, list[dict[str, Any]]] = {}
    order = [str(p) for p in paths]
    bar = tqdm(total=len(order), desc="bench", unit="map", disable=not progress, file=sys.stderr)

    def finish(p: str, rows: list[dict[str, Any]]) -> None:
        done[p] = rows
        bar.update(1)
        best = max((r for r in rows if isinstance(r.get("coverage"), float)), key=lambda r: r["coverage"], default=None)
        bar.set_postfix_str(f"{Path(p).name}: best {best['solver']} {best['coverage']:.3f}" if best else Path(p).name)
        if output is not None:
            write_csv([r for q in order if q in done for r in done[q]], output)

    try:
        if jobs <= 1:
            _worker_init()
            for p in order:
                finish(p, _bench_map_safe(p, settings))
        else:
            ctx = multiprocessing.get_context("spawn")
            with cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=_worker_init) as pool:
                futures = {pool.submit(_bench_map_safe, p, settings): p for p in order}
                for fut in cf.as_completed(futures):
                    p = futures[fut]
                    try:
                        rows = fut.result()
                    except Exception as exc:  # worker died
                        rows = [_row(p, s, status=f"error: worker: {type(exc).__name__}: {exc}"[:300], valid=False)
                                for s in settings.solvers]
                    finish(p, rows)
    finally:
        bar.close()
    return [r for p in order if p in done for r in done[p]]


# --------------------------------------------------------------------------- output


def write_csv(rows: Iterable[Mapping[str, Any]], path: str | Path) -> None:
    """Write rows with the :data:`COLUMNS` header (atomic replace).

    Efficiency columns of extra light curves and the paired differences
    (``efficiency_<name>...``) follow the nine required columns.
    """
    rows = list(rows)
    extra = [k for k in dict.fromkeys(k for r in rows for k in r) if k.startswith("efficiency_") and k not in COLUMNS]
    columns = list(COLUMNS[:9]) + extra + list(COLUMNS[9:])
    path = Path(path)
    if path.parent and not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in columns})
    os.replace(tmp, path)


def read_csv(path: str | Path) -> list[dict[str, Any]]:
    """Read a results CSV back, numbers as floats, ``valid`` as bool."""
    out = []
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            row: dict[str, Any] = {}
            for k, v in r.items():
                if k == "valid":
                    row[k] = v == "True"
                elif k in ("skymap", "solver", "status", "solver_detail", "first_problem", "start", "note",
                           "distance_source", "objective", "detection_stage"):
                    row[k] = v
                else:
                    try:
                        row[k] = float(v) if v != "" else None
                    except ValueError:
                        row[k] = v
            out.append(row)
    return out


def _num(v: Any) -> float | None:
    if v is None or v == "":
        return None
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _by_map(rows: Iterable[Mapping[str, Any]]) -> dict[str, dict[str, Mapping[str, Any]]]:
    out: dict[str, dict[str, Mapping[str, Any]]] = {}
    for r in rows:
        out.setdefault(str(r["skymap"]), {})[str(r["solver"])] = r
    return out


def _scored(r: Mapping[str, Any] | None) -> bool:
    return r is not None and _num(r.get("coverage")) is not None


def best_of(rows: Iterable[Mapping[str, Any]], a: str, b: str) -> list[dict[str, Any]]:
    """The paper's hybrid: per map, the plan of ``a`` or ``b`` with more coverage (``a`` on a tie)."""
    out = []
    for m, sol in _by_map(rows).items():
        ra, rb = sol.get(a), sol.get(b)
        if not (_scored(ra) and _scored(rb)):
            continue
        pick = ra if _num(ra["coverage"]) >= _num(rb["coverage"]) else rb
        d = dict(pick)
        d["solver"] = f"best({a},{b})"
        d["runtime_s"] = (_num(ra.get("runtime_s")) or 0.0) + (_num(rb.get("runtime_s")) or 0.0)
        out.append(d)
    return out


def _wins(rows: Iterable[Mapping[str, Any]], solver: str, other: str, key: str, tie: float) -> tuple[int, int, int]:
    w = l = t = 0
    for sol in _by_map(rows).values():
        a, b = sol.get(solver), sol.get(other)
        if a is None or b is None:
            continue
        x, y = _num(a.get(key)), _num(b.get(key))
        if x is None or y is None:
            continue
        if x > y + tie:
            w += 1
        elif y > x + tie:
            l += 1
        else:
            t += 1
    return w, l, t


def _objective_of(rows: Sequence[Mapping[str, Any]]) -> str:
    """The objective column of a summary line: the rows' one objective, ``mixed``, or ``-`` (older CSVs)."""
    found = sorted({str(r.get("objective") or "") for r in rows} - {""})
    return found[0] if len(found) == 1 else ("mixed" if found else "-")


def _stat(values: list[float], fn: Any) -> str:
    return f"{fn(values):.4f}" if values else "-"


def _mean_err(rows: Sequence[Mapping[str, Any]], key: str) -> tuple[float, float, int, int, int] | None:
    """Mean of per-map paired differences, its error, and maps better / worse beyond 2 sigma / total."""
    pairs = [(_num(r.get(key)), _num(r.get(key + "err"))) for r in rows]
    pairs = [(d, e) for d, e in pairs if d is not None and e is not None]
    if not pairs:
        return None
    d = np.array([x for x, _ in pairs])
    e = np.array([y for _, y in pairs])
    better = int(np.sum(d > 2 * e + 1e-12))
    worse = int(np.sum(d < -2 * e - 1e-12))
    return float(d.mean()), float(np.sqrt(np.sum(e ** 2)) / d.size), better, worse, d.size


def _paired_lines(rows: Sequence[Mapping[str, Any]], solvers: Sequence[str], eff_keys: Sequence[str]) -> list[str]:
    """Summary lines for the paired differences (vs the reference solver; v1 -> fixed source model)."""
    lines: list[str] = []
    diff_solvers = [s for s in solvers
                    if any(_num(r.get(f"efficiency_{k}_diff")) is not None for r in rows if r["solver"] == s
                           for k in eff_keys)]
    if diff_solvers:
        ref = [s for s in solvers if s not in diff_solvers]
        lines += ["", f"paired efficiency differences vs {ref[0] if ref else 'the reference'} (same injections; "
                      "error of the mean = sqrt(sum err^2)/maps; better/worse = beyond 2 sigma on that map):"]
        for s in diff_solvers:
            rs = [r for r in rows if r["solver"] == s]
            parts = []
            for k in eff_keys:
                m = _mean_err(rs, f"efficiency_{k}_diff")
                if m is not None:
                    parts.append(f"{k} {m[0]:+.4f} ± {m[1]:.4f} (better {m[2]}, worse {m[3]} of {m[4]})")
            lines.append(f"  {s}: " + "; ".join(parts))
    if any(_num(r.get(f"efficiency_{k}_v1")) is not None for r in rows for k in eff_keys):
        lines += ["", "first-release scoring (v1: flat 300 s limits, dark before 0.202 d) -> fixed source model, "
                      "same plans (mean v1 -> mean new, paired change ± error):"]
        for s in solvers:
            rs = [r for r in rows if r["solver"] == s]
            parts = []
            for k in eff_keys:
                v1 = [x for x in (_num(r.get(f"efficiency_{k}_v1")) for r in rs) if x is not None]
                v2 = [_num(r.get(f"efficiency_{k}")) for r in rs if _num(r.get(f"efficiency_{k}_v1")) is not None]
                m = _mean_err(rs, f"efficiency_{k}_v1diff")
                if v1 and m is not None:
                    parts.append(f"{k} {np.mean(v1):.4f} -> {np.mean(v2):.4f} ({m[0]:+.4f} ± {m[1]:.4f})")
            if parts:
                lines.append(f"  {s}: " + "; ".join(parts))
    return lines


def summarize(rows: Sequence[Mapping[str, Any]],
              eff_keys: Sequence[str] = ("optimistic", "conservative", "nsbh")) -> str:
    """The summary table: means, medians, validity, wall times, wins/losses.

    Parameters
    ----------
    rows : sequence of mapping
        Result rows (as written to the CSV).
    eff_keys : sequence of str
        Light-curve suffixes of the efficiency columns.

    Returns
    -------
    str
        A plain-text table for stdout (and the issue note).
    """
    rows = list(rows)
    solvers = [s for s in dict.fromkeys(str(r["solver"]) for r in rows)]
    extra = []
    block_name = next((b for b in ("blocks", "milp") if b in solvers), None)
    if block_name and "gwemopt" in solvers:
        extra = best_of(rows, block_name, "gwemopt")
    all_rows = rows + extra
    names = solvers + ([f"best({block_name},gwemopt)"] if extra else [])
    n_maps = len(_by_map(rows))
    lines = [f"maps: {n_maps}; coverage = probability in the planned fields (checker); "
             f"efficiency = detected/injected; times in s (wall clock)"]
    head = (f"{'solver':<20}{'objective':<10}{'n':>4}{'valid':>6}{'cov mean':>10}{'cov med':>9}"
            + "".join(f"{'eff ' + k[:4] + ' mean':>15}" for k in eff_keys)
            + f"{'n_exp mean':>11}{'time med':>10}{'time mean':>10}{'cov/bound':>10}{'c/b med':>9}")
    lines += [head, "-" * len(head)]
    for s in names:
        rs = [r for r in all_rows if r["solver"] == s and _scored(r)]
        cov = [_num(r["coverage"]) for r in rs]
        effs = []
        for k in eff_keys:
            e = [_num(r.get(f"efficiency_{k}")) for r in rs]
            effs.append([x for x in e if x is not None])
        rt = [x for x in (_num(r.get("runtime_s")) for r in rs) if x is not None]
        nexp = [x for x in (_num(r.get("n_exposures")) for r in rs) if x is not None]
        valid = sum(1 for r in rs if r.get("valid") in (True, "True"))
        cb = [x for x in (_num(r.get("coverage_over_bound")) for r in rs) if x is not None]
        lines.append(
            f"{s:<20}{_objective_of(rs):<10}{len(rs):>4}{valid:>6}{_stat(cov, np.mean):>10}{_stat(cov, np.median):>9}"
            + "".join(f"{_stat(e, np.mean):>15}" for e in effs)
            + f"{_stat(nexp, np.mean)[:-2] if nexp else '-':>11}{_stat(rt, np.median)[:-2] if rt else '-':>10}"
            + f"{_stat(rt, np.mean)[:-2] if rt else '-':>10}"
            + f"{_stat(cb, np.mean):>10}{_stat(cb, np.median):>9}"
        )
    missing = {}
    for r in rows:
        if not _scored(r):
            missing.setdefault(str(r["solver"]), []).append(str(r.get("status", ""))[:40])
    for s, sts in missing.items():
        counts: dict[str, int] = {}
        for x in sts:
            counts[x] = counts.get(x, 0) + 1
        lines.append(f"  {s}: {len(sts)} map(s) without a plan: " + ", ".join(f"{k} x{v}" for k, v in counts.items()))
    lines.append("")
    lines.append("A vs B: maps where A wins/loses/ties against B "
                 "(coverage tie <= 1e-4; efficiency tie <= 1e-3):")
    baselines = ("greedy", "gwemopt", "gwemopt-repaired")

    def rank(name: str) -> int:  # the lower rank of a pair is the base it is compared with
        return baselines.index(name) if name in baselines else len(baselines) + names.index(name)

    for i, a in enumerate(names):
        for b in names[i + 1:]:
            base, s = sorted((a, b), key=rank)
            parts = [f"coverage {'%d/%d/%d' % _wins(all_rows, s, base, 'coverage', TIE_COVERAGE)}"]
            for k in eff_keys:
                parts.append(f"eff_{k[:4]} {'%d/%d/%d' % _wins(all_rows, s, base, f'efficiency_{k}', TIE_EFFICIENCY)}")
            lines.append(f"  {s} vs {base}: " + ", ".join(parts))
    lines += _paired_lines(rows, solvers, eff_keys)
    if "gwemopt" in solvers:
        lines.append("")
        lines.append(f"similar-length subset (|n_exposures - gwemopt's| <= {SIMILAR_LENGTH}, the paper's section 4.1):")
        for s in names:
            if s == "gwemopt":
                continue
            pairs = [(sol[s], sol["gwemopt"]) for sol in _by_map(all_rows).values()
                     if _scored(sol.get(s)) and _scored(sol.get("gwemopt"))
                     and abs((_num(sol[s].get("n_exposures")) or 0) - (_num(sol["gwemopt"].get("n_exposures")) or 0))
                     <= SIMILAR_LENGTH]
            if not pairs:
                lines.append(f"  {s}: no map")
                continue
            parts = [f"{len(pairs)} maps", f"coverage {s} {np.mean([_num(a['coverage']) for a, _ in pairs]):.4f}"
                     f" vs gwemopt {np.mean([_num(b['coverage']) for _, b in pairs]):.4f}"]
            for k in eff_keys:
                ea = [_num(a.get(f"efficiency_{k}")) for a, _ in pairs]
                eb = [_num(b.get(f"efficiency_{k}")) for _, b in pairs]
                both = [(x, y) for x, y in zip(ea, eb) if x is not None and y is not None]
                if both:
                    parts.append(f"eff_{k[:4]} {np.mean([x for x, _ in both]):.4f} vs {np.mean([y for _, y in both]):.4f}")
            lines.append(f"  {s}: " + ", ".join(parts))
    return "\n".join(lines)


def make_plots(rows: Sequence[Mapping[str, Any]], directory: str | Path) -> list[Path]:
    """Paper-style figures (PNG, Agg backend).

    ``coverage_scatter.png``: per-map coverage of MUSHROOMS (hybrid, else
    slots, blocks, greedy) against the baseline (gwemopt, else greedy), with
    y = x.  ``efficiency_vs_area.png``: percent improvement in efficiency of
    best-of(MUSHROOMS, baseline) over the baseline against the 90 % area.

    Returns
    -------
    list of pathlib.Path
        Files written (none when fewer than two solvers have plans).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    solvers = set(str(r["solver"]) for r in rows if _scored(r))
    ours = next((s for s in ("hybrid", "slots", "blocks", "milp", "greedy") if s in solvers), None)
    base = next((s for s in ("gwemopt", "greedy") if s in solvers and s != ours), None)
    if ours is None or base is None:
        return []
    pairs = [(sol[ours], sol[base]) for sol in _by_map(rows).values()
             if _scored(sol.get(ours)) and _scored(sol.get(base))]
    written = []
    fig, ax = plt.subplots(figsize=(5, 5))
    ok = [bool(a.get("valid") in (True, "True") and b.get("valid") in (True, "True")) for a, b in pairs]
    for flag, style in ((True, dict(c="C0", label="both plans valid")),
                        (False, dict(facecolors="none", edgecolors="C3", label="a plan fails the checker"))):
        x = [_num(a["coverage"]) for (a, _), v in zip(pairs, ok) if v == flag]
        y = [_num(b["coverage"]) for (_, b), v in zip(pairs, ok) if v == flag]
        if x:
            ax.scatter(x, y, s=16, **style)
    ax.plot([0, 1], [0, 1], color="gold", lw=1.5, label="y = x")
    ax.set_xlabel(f"probability coverage, {ours}")
    ax.set_ylabel(f"probability coverage, {base}")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_title(f"{len(pairs)} sky maps (below the line: {ours} better)")
    ax.legend(loc="upper left")
    fig.tight_layout()
    out = directory / "coverage_scatter.png"
    fig.savefig(out, dpi=120)
    plt.close(fig)
    written.append(out)

    fig, ax = plt.subplots(figsize=(7, 4.5))
    plotted = 0
    for k, marker in (("conservative", "o"), ("optimistic", "^")):
        xs, ys = [], []
        for a, b in pairs:
            area = _num(a.get("area90_deg2"))
            ea, eb = _num(a.get(f"efficiency_{k}")), _num(b.get(f"efficiency_{k}"))
            if area is None or ea is None or eb is None or eb <= 0:
                continue
            hybrid = ea if _num(a["coverage"]) >= _num(b["coverage"]) else eb
            xs.append(area)
            ys.append(100.0 * (hybrid - eb) / eb)
        ax.scatter(xs, ys, s=16, marker=marker, label=f"{k} light curve", alpha=0.8)
        plotted += len(xs)
    ax.axhline(0, color="grey", lw=0.8)
    if plotted:  # a log axis needs a point (no map with a nonzero baseline efficiency: an empty figure)
        ax.set_xscale("log")
    ax.set_xlabel("90% credible area (deg$^2$)")
    ax.set_ylabel(f"efficiency gain of best({ours},{base})\nover {base} (%)")
    ax.legend()
    fig.tight_layout()
    out = directory / "efficiency_vs_area.png"
    fig.savefig(out, dpi=120)
    plt.close(fig)
    written.append(out)
    return written


# --------------------------------------------------------------------------- CLI


def _load_settings(args: Any) -> BenchSettings:
    from ..config import ConfigError, Config, read_config_table
    from ..scheduler_core.errors import InputError

    bench_table: Mapping[str, Any] = {}
    if getattr(args, "config", None):
        p = Path(args.config)
        data = read_config_table(p)
        bench_table = data.pop("bench", {}) or {}
        config = Config.from_mapping(data, source=str(p)).scheduler
    else:
        config = Config().scheduler
    solvers = tuple(s.strip() for s in str(args.solvers).split(",") if s.strip())
    bad = [s for s in solvers if not is_row_name(s)]
    if bad or not solvers:
        raise InputError(f"unknown solver(s) {', '.join(bad) or '(none)'}; choose from {', '.join(SOLVERS)} "
                         f"(ours also as <solver>{' or <solver>'.join(OBJECTIVE_SUFFIXES)})")
    if args.injections < 1:
        raise InputError(f"--injections must be >= 1, got {args.injections}")
    if getattr(args, "jobs", 1) < 1:
        raise InputError(f"--jobs must be >= 1, got {args.jobs}")
    start_iso = None
    if getattr(args, "start", None):
        from ..scheduler_core.times import parse_time

        start_iso = parse_time(args.start, "--start", mjd=True).isot
    try:
        return BenchSettings.from_mapping(bench_table, config=config, solvers=solvers, start_iso=start_iso,
                                          n_injections=int(args.injections))
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"[bench]: {exc}") from None


def main(args: Any) -> int:
    """``mushrooms bench SKYMAP_DIR ...``: run, write the CSV, print the summary.

    Returns
    -------
    int
        0 when every map was processed (individual solver failures are rows
        in the CSV, not errors); 2 on bad input.
    """
    settings = _load_settings(args)
    paths = skymaps_in(args.skymap_dir)
    if {"gwemopt", "gwemopt-repaired"} & set(settings.solvers):
        from .gwemopt_baseline import ENV_PYTHON, gwemopt_python

        if gwemopt_python(settings.gwemopt_python) is None:  # (mushrooms.tool.bench refuses it without a cache)
            print(f"mushrooms bench: gwemopt unavailable (pip install 'mushrooms[gwemopt]', or set ${ENV_PYTHON} "
                  f"to its interpreter); its rows will say 'unavailable' where the cache "
                  f"{settings.gwemopt_cache_dir} has no schedule", file=sys.stderr)
    t0 = time.perf_counter()
    rows = run_bench(paths, settings, jobs=args.jobs, output=args.output,
                     progress=os.environ.get("MUSHROOMS_PROGRESS", "1") != "0")
    write_csv(rows, args.output)
    print(summarize(rows, tuple(settings.lightcurves)))
    print(f"\n{len(paths)} map(s), solvers {','.join(settings.solvers)}, jobs {args.jobs}, "
          f"{settings.n_injections} injections/map, wall {time.perf_counter() - t0:.0f} s; CSV: {args.output}")
    if args.plots:
        for p in make_plots(rows, args.plots):
            print(f"plot: {p}")
    return 0
