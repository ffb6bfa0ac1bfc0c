"""One sky map benchmarked: the problem prepared once, every requested row planned and scored.

The problem is prepared once per map (same horizon, fields, footprints and
windows for every row); each of our rows runs
:func:`~mushrooms.scheduler_core.planner.optimise` exactly as ``make_plan``
publishes under the configuration given (its ``objective`` included;
``<solver>-coverage`` / ``<solver>-detection`` force one objective, and the
CSV column ``objective`` says which each row used); ``gwemopt`` runs the real
gwemopt through :mod:`~mushrooms.evaluation.gwemopt_baseline`, and
``gwemopt-repaired`` is the same schedule with every rule-breaking exposure
removed (:func:`~mushrooms.evaluation.gwemopt_baseline.repair_observations`);
``gwemopt-o4`` and ``gwemopt-skyportal`` run gwemopt under their named
configurations (:mod:`~mushrooms.evaluation.gwemopt_options`) and are judged
under the configuration with their filter sequence and exposure;
``service`` is what the daemon publishes (:func:`service_row`: the anytime
flow, the better-by-a-margin rule, the not-observable answer), ``service-grg``
the same under the keys of :data:`~.settings.KEYED_ROWS`.
Every plan is judged by :func:`~.scoring.score_plan` with the map's one set of
injections.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..commit import code_commit
from .rows import fmt, make_row, num
from .scoring import pair_with_reference, score_plan
from .settings import GWEMOPT_ROWS, SERVICE_ROW, BenchSettings, arm_config, keyed_row, row_arm, row_solver

__all__ = ["MapScene", "bench_map", "open_map", "service_row"]

log = logging.getLogger(__package__)  # the benchmark's one logger ("mushrooms.evaluation.bench")

Row = dict[str, Any]
Hits = dict[str, np.ndarray]


@dataclass
class MapScene:
    """What every row of one map shares.

    Attributes
    ----------
    name : str
        The map as the rows name it (its path).
    path : str or pathlib.Path
        The sky map file.
    skymap : SkyMap
        The map at the configuration's resolution.
    start : astropy.time.Time
        Horizon start of every plan.
    merger : astropy.time.Time
        When the light curves start (the event time, else the start).
    common : dict
        Cells of every row of the map (area, distance, start, injections, bound).
    note : str
        The map's note (no event time, no distance layers).
    lightcurves : dict
        Column suffix -> loaded light curve.
    injections : Injections or None
        The map's kilonova injections (None: no distance layers).
    footprints : Footprints
        ZTF field footprints at the map's resolution.
    problem : PlanningProblem or None
        The prepared problem (None: ``prep_error`` says why).
    prepare_s : float
        Wall time of the preparation (s).
    prep_error : str
        Why there is no problem.
    bound : float or None
        Certified coverage upper bound of the problem.
    gwemopt_runs : dict
        gwemopt's runs on the map per named configuration, made by the first row that needs one and shared
        (``gwemopt`` and ``gwemopt-repaired`` share one).
    """

    name: str
    path: str | Path
    skymap: Any
    start: Any
    merger: Any
    common: dict[str, Any]
    note: str
    lightcurves: dict[str, Any]
    injections: Any
    footprints: Any
    problem: Any = None
    prepare_s: float = 0.0
    prep_error: str = ""
    bound: float | None = None
    gwemopt_runs: dict[str, Any] = field(default_factory=dict, repr=False)

    def row(self, solver: str, **values: Any) -> Row:
        """A row of this map with its common cells."""
        return make_row(self.name, solver, **{**self.common, **values})

    def failed(self, solver: str, status: str, **values: Any) -> Row:
        """A row without a plan."""
        return self.row(solver, status=status, valid=False, **values)

    def with_bound(self, scores: dict[str, Any]) -> dict[str, Any]:
        """``scores`` with ``coverage_over_bound`` when both are known."""
        cov = num(scores.get("coverage"))
        if self.bound is not None and cov is not None and self.bound > 0:
            scores["coverage_over_bound"] = fmt(cov / self.bound, 4)
        return scores


def bench_map(path: str | Path, settings: BenchSettings, raise_errors: bool = False) -> list[Row]:
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
        One row (keys :data:`~.rows.COLUMNS`) per solver; failures become
        rows with a ``status`` saying why.
    """
    scene = open_map(path, settings, raise_errors)
    if isinstance(scene, list):
        return [{**row, "commit": code_commit()} for row in scene]
    rows: list[Row] = []
    hits: dict[str, Hits] = {}
    for solver in settings.solvers:
        try:
            row, mine = _solver_row(scene, solver, settings)
        except Exception as exc:  # one broken solver must not stop the benchmark
            if raise_errors:
                raise
            log.exception("%s on %s failed", solver, scene.name)
            row, mine = scene.failed(solver, f"error: {type(exc).__name__}: {exc}"[:300], note=scene.note), None
        row["commit"] = code_commit()
        rows.append(row)
        if mine is not None:
            hits[solver] = mine
    pair_with_reference(rows, hits, settings.reference)
    return rows


def _solver_row(scene: MapScene, solver: str, settings: BenchSettings) -> tuple[Row, Hits | None]:
    """The row of one solver on the map, and its detections (None without a plan)."""
    if solver in GWEMOPT_ROWS:
        return _gwemopt_row(scene, solver, settings)
    if scene.problem is None:
        return scene.failed(solver, scene.prep_error or "prepare_error", note=scene.note), None
    if keyed_row(solver)[0] == SERVICE_ROW:
        return service_row(scene, solver, settings)
    return _our_row(scene, solver, settings)


# --------------------------------------------------------------------------- the map


def open_map(path: str | Path, settings: BenchSettings, raise_errors: bool = False) -> MapScene | list[Row]:
    """Read a map and prepare what its rows share; the rows of a map that cannot be planned instead."""
    from ...scheduler_core.errors import InputError
    from ...scheduler_core.sky.skymap import read_skymap

    name = str(path)
    try:
        skymap = read_skymap(path, nside=settings.config.nside)
    except InputError as exc:
        if raise_errors:
            raise
        return [make_row(name, s, status=f"skymap_error: {exc}", valid=False) for s in settings.solvers]
    start = _start(skymap, settings)
    if start is None:
        return [make_row(name, s, status="no_start: map has no event time; give --start", valid=False)
                for s in settings.solvers]
    scene = _scene(name, path, skymap, start, settings)
    _prepare(scene, settings, raise_errors)
    return scene


def _start(skymap: Any, settings: BenchSettings) -> Any:
    """The horizon start: ``settings.start_iso``, else the map's event time, else None."""
    from astropy.time import Time

    from ...scheduler_core.plan.document import parse_time

    if settings.start_iso:
        return parse_time(settings.start_iso)
    if skymap.event_time is not None:
        return Time(skymap.event_time, scale="utc")
    return None


def _scene(name: str, path: str | Path, skymap: Any, start: Any, settings: BenchSettings) -> MapScene:
    """The map's cells, notes, light curves, injections and footprints (no problem yet)."""
    from ...scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from ...scheduler_core.source.lightcurves import load_lightcurve
    from ..efficiency import draw_injections

    common = dict(area90_deg2=fmt(skymap.credible_area(0.9), 2),
                  distmean_mpc=fmt(skymap.distmean, 2) if skymap.distmean is not None else "",
                  start=start.isot + "Z")
    notes = []
    if skymap.event_time is None:
        notes.append("no event time: merger taken at the horizon start")
    lightcurves = {k: load_lightcurve(v) for k, v in settings.bench.lightcurves.items()}
    injections = draw_injections(skymap, settings.n_injections, fixed_distance_mpc=settings.bench.fixed_distance_mpc)
    if injections is None:
        notes.append("no distance layers: efficiency skipped (set [bench] fixed_distance_mpc)")
    else:
        common.update(n_injections=len(injections), distance_source=injections.distance_source)
    footprints = field_footprints(load_ztf_fields(), settings.config.nside)
    merger = skymap.event_time if skymap.event_time is not None else start
    return MapScene(name=name, path=path, skymap=skymap, start=start, merger=merger, common=common,
                    note="; ".join(notes), lightcurves=lightcurves, injections=injections, footprints=footprints)


def _prepare(scene: MapScene, settings: BenchSettings, raise_errors: bool) -> None:
    """Prepare the map's one problem and its coverage bound (every row needs it: ours to plan, gwemopt's
    for the repair and the bound); a failure is kept in ``prep_error`` for each row to report."""
    from ...scheduler_core.prepare import prepare_problem
    from ...scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound

    t0 = time.perf_counter()
    try:
        scene.problem = prepare_problem(scene.skymap, settings.config, scene.start)
    except Exception as exc:  # reported per solver
        if raise_errors:
            raise
        scene.prep_error = f"prepare_error: {type(exc).__name__}: {exc}"
    scene.prepare_s = time.perf_counter() - t0
    # the bound plans publish: min(U4, V) within [scheduler] bound_time_limit_s
    scene.bound = certified_upper_bound(scene.problem).value if scene.problem is not None else None
    if scene.bound is not None:
        scene.common.update(bound=fmt(scene.bound))


# --------------------------------------------------------------------------- our rows


def row_config(config: Any, solver: str, settings: BenchSettings) -> tuple[str, Any, str]:
    """``(scheduler, configuration, objective)`` of one of our rows.

    A forced objective (``-coverage``, ``-detection``) replaces the
    configuration's; ``-detection`` rows get ``[bench] detection_extra_s``
    on top of ``time_limit_s``.  ``greedy`` rows are coverage rows whatever
    the objective.  A row ``<row>@<arm>`` is planned under the configuration
    with ``[bench.arms.<arm>]``'s keys replaced (before the forced objective);
    a keyed row (``service-grg``) under its own keys first.
    """
    base, forced = row_solver(solver)
    keyed, keys = keyed_row(solver)
    if keys is not None:
        base, config = keyed, arm_config(config, row_arm(solver)[0], keys)
    arm = row_arm(solver)[1]
    if arm is not None:
        config = arm_config(config, arm, settings.bench.arms[arm])
    rcfg = config if forced is None else dataclasses.replace(config, objective=forced)
    extra = settings.bench.detection_extra_s
    if forced == "detection" and extra > 0:
        rcfg = dataclasses.replace(rcfg, time_limit_s=config.time_limit_s + extra, detection_time_limit_s=extra)
    return base, rcfg, ("coverage" if base == "greedy" else rcfg.objective)


def _our_row(scene: MapScene, solver: str, settings: BenchSettings) -> tuple[Row, Hits | None]:
    """Plan with one of our schedulers as ``make_plan`` would (the scheduler, then the detection stage if
    asked), build the plan without raising on the checker, and score it."""
    from ...scheduler_core.planner import build_plan, optimise

    base, rcfg, objective = row_config(settings.config, solver, settings)
    planned = scene.problem if rcfg == settings.config else dataclasses.replace(scene.problem, config=rcfg)
    t0 = time.perf_counter()
    try:
        result = optimise(planned, scene.skymap, base)
        solve_s = time.perf_counter() - t0
    except ImportError as exc:
        return scene.failed(solver, "unavailable", note=f"{exc}"), None
    stage = detection_stage_text(result) if objective == "detection" else ""
    plan = build_plan(planned, result, scene.skymap, base)
    scores, hits = score_plan(plan, scene.skymap, dataclasses.replace(settings, config=rcfg), scene.footprints,
                              scene.injections, scene.lightcurves, scene.merger)
    arm = row_arm(solver)[1]
    if arm is not None and result.upper_bound is not None:  # the arm's own bound (a menu's is its shortest exposure's)
        cov = num(scores.get("coverage"))
        scores.update(bound=fmt(result.upper_bound.value))
        if cov is not None and result.upper_bound.value > 0:
            scores["coverage_over_bound"] = fmt(cov / result.upper_bound.value, 4)
    else:
        scores = scene.with_bound(scores)
    row = scene.row(solver, status=result.status, mip_gap=fmt(result.mip_gap), arm=arm or "",
                    runtime_s=fmt(scene.prepare_s + solve_s, 3), prepare_s=fmt(scene.prepare_s, 3),
                    solve_s=fmt(solve_s, 3), solver_detail=result.solver, note=scene.note, detection_stage=stage,
                    objective=objective, **scores)
    return row, hits


def service_row(scene: MapScene, solver: str, settings: BenchSettings) -> tuple[Row, Hits | None]:
    """What the daemon publishes for the map under the configuration, scored: the anytime flow.

    The fast plan is revision 1 (:func:`~mushrooms.scheduler_core.anytime.first_plan`);
    ``config.solver``'s plan (:func:`~mushrooms.scheduler_core.anytime.optimised_plan`,
    the detection stage included under ``objective = "detection"``) replaces it
    as :func:`~mushrooms.scheduler_core.anytime.supersession` decides (the
    daemon's rule: it passes the checker and ``min_coverage`` and is better by
    ``settings.supersede_min_gain``).
    A published plan below ``min_coverage`` is the ``not_observable`` answer:
    no exposures, so coverage and efficiencies 0, status ``not_observable``.
    ``solver_detail`` says which revision stands.  (The daemon's horizon
    starts at the alert's receipt; here at the map's event time.)
    """
    from ...scheduler_core.anytime import FIRST_SOLVER, first_plan, optimised_plan, supersession
    from ...scheduler_core.errors import PlanCheckError
    from ...scheduler_core.plan.observability import not_observable

    _, rcfg, objective = row_config(settings.config, solver, settings)
    problem = scene.problem if rcfg == settings.config else dataclasses.replace(scene.problem, config=rcfg)
    t0 = time.perf_counter()
    published = first = first_plan(problem, scene.skymap)
    stage = f"revision 1 ({FIRST_SOLVER})"
    if rcfg.solver != FIRST_SOLVER:
        try:
            better = optimised_plan(problem, scene.skymap, rcfg.solver, first)
        except PlanCheckError:
            better = None
        decided = supersession(first, better, scene.skymap, rcfg, settings.supersede_min_gain)
        published, stage = decided.plan, _service_stage(decided.reason, rcfg, settings.supersede_min_gain)
    solve_s = time.perf_counter() - t0
    status, note = published.metrics.status, scene.note
    answer = not_observable(published, scene.skymap, rcfg)
    if answer is not None:
        status, note = "not_observable", "; ".join(filter(None, [note, " ".join(answer.sentences)]))[:300]
        published = published.with_(observations=(), metrics=dataclasses.replace(
            published.metrics, coverage=0.0, n_fields=0, n_exposures=0, expected_detections=0.0,
            coverage_as_executed=0.0))
    scores, hits = score_plan(published, scene.skymap, dataclasses.replace(settings, config=rcfg), scene.footprints,
                              scene.injections, scene.lightcurves, scene.merger)
    row = scene.row(solver, status=status, arm=row_arm(solver)[1] or "", runtime_s=fmt(scene.prepare_s + solve_s, 3),
                    prepare_s=fmt(scene.prepare_s, 3), solve_s=fmt(solve_s, 3),
                    solver_detail=f"{stage}; {published.metrics.solver}", note=note, objective=objective,
                    **scene.with_bound(scores))
    return row, hits


def _service_stage(reason: str, config: Any, gain: float) -> str:
    """The ``solver_detail`` head of the ``service`` row: which revision stands, after :func:`supersession`."""
    from ...scheduler_core.anytime import FIRST_SOLVER

    stands = f"revision 1 ({FIRST_SOLVER}) stands"
    return {
        "better": f"revision 2 ({config.solver})",
        "no_plan": f"{stands}: the {config.solver} plan failed the checker",
        "below_min_coverage": f"{stands}: {config.solver} below min_coverage {config.min_coverage:g}",
        "not_better": f"{stands}: {config.solver} not better by {gain:g}",
    }[reason]


def detection_stage_text(result: Any) -> str:
    """The ``detection_stage`` cell: the stage's choice, budget, time and grids (empty without a stage)."""
    d = result.detection
    if d is None:
        return ""
    solved = [g for g in d.grids if "expected_detections" in g]
    return (f"{d.choice}; budget {d.budget_s} s, took {d.runtime_s} s; {len(solved)} grid(s) solved, "
            f"{sum(not g['above_floor'] for g in solved)} below the floor")


# --------------------------------------------------------------------------- gwemopt's rows


def _gwemopt_row(scene: MapScene, solver: str, settings: BenchSettings) -> tuple[Row, Hits | None]:
    """gwemopt's schedule of the map under the row's named configuration (run once per configuration), repaired
    for ``gwemopt-repaired``, judged under the configuration with the row's filters and exposure, scored."""
    import dataclasses as dc

    from ..gwemopt_baseline import gwemopt_plan
    from ..gwemopt_options import GWEMOPT_CONFIGS, LEGACY, row_planning_config

    named = GWEMOPT_CONFIGS[LEGACY if solver == "gwemopt-repaired" else solver]
    run = _gwemopt_run(scene, settings, named)
    if run.status != "ok":
        return scene.failed(solver, run.status, runtime_s=fmt(run.runtime_s, 3),
                            note="; ".join(filter(None, [scene.note, run.message]))), None
    rcfg = row_planning_config(settings.config, named)
    detail = f"gwemopt 0.4.2 {named.name}" + (" (cached)" if run.message == "cached" else "")
    extra_note = ""
    if solver == "gwemopt-repaired":
        if scene.problem is None:
            return scene.failed(solver, scene.prep_error or "prepare_error", note=scene.note), None
        run, counts = _repaired(run, scene.problem)
        detail += "; repaired"
        extra_note = "repair: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v)
    ids = {o.field_id for o in run.observations}
    cov = scene.footprints.coverage(ids, scene.skymap.prob) if ids else 0.0
    plan = gwemopt_plan(run, scene.start, rcfg, scene.skymap.sha256, cov, name=named.name)
    if solver == "gwemopt-repaired":
        plan = dc.replace(plan, metrics=dc.replace(plan.metrics, solver=solver))
    scores, hits = score_plan(plan, scene.skymap, dc.replace(settings, config=rcfg), scene.footprints,
                              scene.injections, scene.lightcurves, scene.merger)
    row = scene.row(solver, status=run.status, runtime_s=fmt(run.runtime_s, 3), solve_s=fmt(run.runtime_s, 3),
                    solver_detail=detail, objective="coverage",
                    note="; ".join(filter(None, [scene.note, extra_note])), **scene.with_bound(scores))
    return row, hits


def _gwemopt_run(scene: MapScene, settings: BenchSettings, named: Any) -> Any:
    """gwemopt's run on the map under one named configuration (its cache, or the real gwemopt), made once per
    map; a configuration with ``credible_fields`` tiles only the fields SkyPortal would hand it."""
    from ..gwemopt_baseline import run_gwemopt
    from ..gwemopt_options import credible_fields

    if named.name not in scene.gwemopt_runs:
        b = settings.bench
        fields = (credible_fields(scene.footprints, scene.skymap.prob, named.credible_fields)
                  if named.credible_fields is not None else None)
        scene.gwemopt_runs[named.name] = run_gwemopt(
            scene.path, scene.start, settings.config, python=b.gwemopt_python, timeout_s=b.gwemopt_timeout_s,
            cache_dir=b.gwemopt_cache_dir, cache_only=b.gwemopt_cache_only, named=named, fields=fields)
    return scene.gwemopt_runs[named.name]


def _repaired(run: Any, problem: Any) -> tuple[Any, dict[str, int]]:
    """gwemopt's run with every exposure that breaks our rules removed, and how many of each were."""
    from ..gwemopt_baseline import repair_observations

    fixed = repair_observations(run.observations, problem)
    return dataclasses.replace(run, observations=fixed.observations), fixed.counts
