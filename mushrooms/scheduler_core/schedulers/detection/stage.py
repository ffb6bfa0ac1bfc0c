"""The detection objective on the slot model: plan for the kilonova found, not only the area covered.

Coverage counts a cell once any field holding it is observed, however
shallow or late the exposure.  The detection objective counts what the
evaluation counts: the probability that the source, at the cell's distance
posterior, is brighter than the limit of the best exposure covering it
(:mod:`.`, equation X1).  The model (reaches X2, distance
levels, X3-X6 on the slot grid) is :mod:`.model`; this module
is the stage that solves it.

The stage starts from a coverage plan (mapped onto each grid, the solver's
first incumbent), solves the portfolio's grids within its own budget,
times every solution with the real overheads (:func:`..slots.schedule.time_slot_plan`)
and scores the executable plans exactly with (X1).  It returns the coverage
plan itself unless a detection plan, as it will be published (after the
real timing and the least-gain rule), has more expected detections *and*
still respects the floor (X6), or, when the expected detections tie
(closer than ``config.min_gain``, e.g. both ~0 for a source too far for the
light curve), covers more by ``min_gain`` (:mod:`...preference`, R1-R3): it
never publishes fewer detections than the plan it started from (beyond the
margin), nor loses more than ``ε`` of its coverage, nor keeps a plan over
one with as many expected detections and more coverage.
"""

from __future__ import annotations

import dataclasses
import logging
import time

import numpy as np
from astropy.time import TimeDelta

from ...sequences import require_pair
from ...sky.cells import merge_cells
from ...source.depth import ZTF_DEPTH, DepthModel
from .ceiling import detection_ceiling
from .model import (build_detection_model, detection_start_vector, distance_levels, level_weights,
                              pair_levels, pair_reach)
from ..gain import drop_low_gain
from ...preference import is_preferred
from ...source.kilonova import Kilonova, load_kilonova
from ...plan.document import Observation, Plan, PlanMetrics
from ...problem import DetectionReport, PlanningProblem, ScheduleResult, StopCheck
from ...sky.skymap import SkyMap
from ..slots.exposure_menu import (dominated_pairs, map_start_menu, menu_instance, menu_portfolio, menu_positions,
                            menu_start_pairs)
from ..slots.model import SlotInstance, slot_instance
from ..milp.solvers import resolve_backend, solve_milp
from ..as_executed import AS_EXECUTED_MEMO

__all__ = ["plan_expected_detections", "detection_stage", "coverage_floor"]

log = logging.getLogger(__name__)

#: Least solve time (s) worth starting a grid with; below it the stage stops.
MIN_SOLVE_S = 0.3

#: Share of the stage's time left given to the first grid (the coverage plan's own, warm-started):
#: on 12 shared maps 0.9 found more than 0.5 (solving one grid well beats a wide, shallow portfolio).
FIRST_GRID_SHARE = 0.9

#: The stage solves at most this many grids (the coverage plan's own first); None: as many as its budget allows.
#: Measured on the 56 shared maps, the same coverage plans side by side (``benchmarks/quality/detection_stage_variants.py``,
#: ``benchmarks/results/speed/runs/detection_stage_variants_56maps_b.txt``): the plan kept came from the first four grids on 11
#: of the 16 maps where a detection plan won; 4 grids with a 2.5 s budget instead of every grid in 4 s saved a
#: median 1.25 s per map for -0.0005 +- 0.0003 expected detections (-0.35 %; 6 maps worse, by up to 0.009), but
#: in the whole default, side by side with the last release, expected detections fell by 0.007 a map, most of
#: it two maps whose best detection plan only some runs find (bns_o3/1, bns_o3/10: 0.13-0.17 each).  Not adopted.
MAX_GRIDS: int | None = None

#: With an exposure menu: share of the stage's time left given to the fixed exposure's own grid, solved
#: first (small, fast); the first menu grid, warm-started from the best plan so far, gets FIRST_GRID_SHARE
#: of what is left after it.
MENU_FIXED_SHARE = 0.3


def coverage_floor(coverage: float, max_loss: float, baseline: float | None = None) -> float:
    """The least coverage a detection plan may have (X6): ``max((1 - ε) C₀, min(C_g, C₀))``.

    Parameters
    ----------
    coverage : float
        ``C₀``, the published coverage of the coverage plan the stage starts from.
    max_loss : float
        ``ε``, ``config.detection_max_coverage_loss`` (relative).
    baseline : float, optional
        ``C_g``, the published coverage of greedy's plan when known: a
        detection plan never covers less than the fast heuristic's (nor
        need it cover more than ``C₀``, which the coverage plan itself meets).
    """
    floor = (1.0 - max_loss) * coverage
    return floor if baseline is None else max(floor, min(float(baseline), coverage))


def plan_expected_detections(problem: PlanningProblem, skymap: SkyMap, observations: tuple[Observation, ...] | list,
                             kilonova: Kilonova, depth: DepthModel = ZTF_DEPTH) -> float:
    """Exact expected detections (X1) of scheduled exposures."""
    from ...source.detection import expected_detections

    problem.clock.step("score", len(observations))  # (A3)
    plan = Plan("candidate", problem.start, problem.start + TimeDelta(problem.horizon_s, format="sec"),
                tuple(observations), PlanMetrics(0.0, "", "", None, 0.0, 0, len(observations)))
    e = expected_detections(plan, skymap, problem.footprints, kilonova, skymap.event_time, depth)
    return 0.0 if e is None else e


def detection_stage(problem: PlanningProblem, skymap: SkyMap, coverage: ScheduleResult,
                    should_stop: StopCheck | None = None, kilonova: Kilonova | None = None,
                    depth: DepthModel = ZTF_DEPTH, time_limit_s: float | None = None,
                    baseline_coverage: float | None = None, baseline_executed: float | None = None) -> ScheduleResult:
    """Improve a coverage plan's expected detections on the slot grids, within a coverage floor.

    Parameters
    ----------
    problem : PlanningProblem
        Uses ``config.detection_lightcurve``, ``detection_levels``,
        ``detection_coverage_weight``, ``detection_max_coverage_loss``, the
        slot and solver settings.
    skymap : SkyMap
        Distance layers and merger time (``event_time``).
    coverage : ScheduleResult
        The coverage plan to start from (any scheduler's).
    should_stop : callable, optional
        Polled by the solver.
    kilonova : Kilonova, optional
        Default: ``config.detection_lightcurve``.
    depth : DepthModel
        Limiting-magnitude model.
    time_limit_s : float, optional
        Budget (s, on ``problem.clock``: wall or work seconds) of the whole
        stage (scoring, models, solves, timing); default ``config.detection_time_limit_s``.  A grid is only
        started when at least :data:`MIN_SOLVE_S` of solve time is left
        after the time its solution will take to time and score.
    baseline_coverage : float, optional
        Published coverage of the fast heuristic's plan (greedy's, in the
        hybrid's portfolio): the floor (X6) is at least this, so the stage
        never returns a plan covering less than greedy's.
    baseline_executed : float, optional
        The same plan's coverage as ZTF's scheduler executes its queues
        (Q14), when known: the floor as executed (X10) is at least
        ``min(this, Cx₀)``.

    Returns
    -------
    ScheduleResult
        The detection plan when, as it will be published (after the
        least-gain rule), it has more expected detections (X1) than
        ``coverage`` by ``config.min_gain`` and covers at least
        ``max((1 - ε) C₀, min(C_g, C₀))`` (X6, :func:`coverage_floor`; ``C₀``
        is ``coverage``'s published coverage, ``C_g``
        ``baseline_coverage``), or ties on expected
        detections and covers more by ``min_gain`` (R1-R3), and, as ZTF's
        scheduler executes its queues, covers at least
        ``max((1 - ε) Cx₀, min(Cx_g, Cx₀))`` (X10: ``Cx₀`` the coverage
        plan's executed coverage, ``Cx_g`` ``baseline_executed``); else
        ``coverage`` itself.  ``expected_detections`` (and
        ``expected_detections_lightcurve``) hold the returned plan's score,
        ``detection`` (:class:`~...problem.DetectionReport`) the choice, the
        coverage plan's score, the floor and the per-grid runs.
    """
    require_pair(problem.config.filters, "detection stage")
    t_wall = time.perf_counter()
    cfg = problem.config
    budget = cfg.detection_time_limit_s if time_limit_s is None else float(time_limit_s)
    own_kilonova = kilonova is None
    kilonova = kilonova or load_kilonova(cfg.detection_lightcurve)
    if not skymap.has_distance or skymap.event_time is None:
        return _kept_coverage(coverage, t_wall, "coverage (no distance layers)", budget, None, ())
    stage = _Stage(problem, skymap, kilonova, depth, should_stop, budget, problem.clock.mark())
    t_score = problem.clock.mark()
    c_cov, e_cov = stage.published(coverage)
    stage.post_s = problem.clock.since(t_score) + 0.1  # time to time and score one solution (updated as measured)
    floor = coverage_floor(c_cov, cfg.detection_max_coverage_loss, baseline_coverage)
    lightcurve = cfg.detection_lightcurve if own_kilonova else None
    ceiling = detection_ceiling(problem, skymap, kilonova, depth)
    if ceiling < e_cov + cfg.min_gain:  # (X7) no plan detects min_gain more: the answer cannot change
        log.info("detection objective skipped: no plan can have more than %.4f expected detections, the coverage "
                 "plan has %.4f", ceiling, e_cov)
        return _kept_coverage(coverage, t_wall, "coverage (at the detection ceiling)", budget,
                              (e_cov, floor, lightcurve), ())
    # (X6) the model keeps (1 - ε) C₀: a floor at C₀ itself (greedy's plan kept) would refuse the coverage plan's
    # own mapped start, which the grid's rounding puts a little below it, and leave the solver without one
    model_floor = coverage_floor(c_cov, cfg.detection_max_coverage_loss)
    # (X10) the floor as executed: what ZTF's scheduler does with the coverage plan's queues, and greedy's
    stage.executed_floor = coverage_floor(stage.executed(coverage), cfg.detection_max_coverage_loss, baseline_executed)
    best, runs = stage.solve_grids(coverage, model_floor, floor, (e_cov, None, None, c_cov))
    memo = {**coverage.details.get(AS_EXECUTED_MEMO, {}), **stage.memo}
    coverage = dataclasses.replace(coverage, details=dict(coverage.details, **{AS_EXECUTED_MEMO: memo}))
    if best[1] is None:
        return _kept_coverage(coverage, t_wall, "coverage", budget, (e_cov, floor, lightcurve), tuple(runs))
    e, obs, res, c = best
    report = DetectionReport("detection", round(budget, 3), round(time.perf_counter() - t_wall, 3), e_cov, floor,
                             tuple(runs))
    log.info("detection objective: expected detections %.4f -> %.4f, coverage %.4f -> %.4f (floor %.4f)",
             e_cov, e, c_cov, c, floor)
    # the coverage plan's other fields (its MILP bound, certified upper bound, ...) stay as they were
    return dataclasses.replace(coverage, observations=tuple(obs), solver=f"detection({coverage.solver})",
                               status=res.status, mip_gap=res.gap,
                               runtime_s=coverage.runtime_s + (time.perf_counter() - t_wall),
                               expected_detections=e, expected_detections_lightcurve=lightcurve, detection=report)


def _kept_coverage(coverage: ScheduleResult, t_wall: float, choice: str, budget: float,
                   scored: tuple[float, float, str | None] | None, runs: tuple[dict, ...]) -> ScheduleResult:
    """The coverage plan, as the detection stage returns it when it keeps it.

    ``scored`` is (its expected detections, the floor, the light curve), None
    without distance layers.
    """
    e_cov, floor, lightcurve = scored if scored is not None else (None, None, coverage.expected_detections_lightcurve)
    report = DetectionReport(choice, round(budget, 3), round(time.perf_counter() - t_wall, 3), e_cov, floor, runs)
    return dataclasses.replace(coverage, runtime_s=coverage.runtime_s + (time.perf_counter() - t_wall),
                               expected_detections=e_cov, expected_detections_lightcurve=lightcurve,
                               detection=report)


class _Stage:
    """The detection stage's solves on the slot grids of one problem, within one budget."""

    def __init__(self, problem: PlanningProblem, skymap: SkyMap, kilonova: Kilonova, depth: DepthModel,
                 should_stop: StopCheck | None, budget: float, started: tuple) -> None:
        self.problem, self.skymap, self.kilonova, self.depth = problem, skymap, kilonova, depth
        self.should_stop, self.budget, self.started = should_stop, budget, started  # started: the clock's mark
        self.post_s = 0.1
        self.levels: np.ndarray | None = None
        self.W: np.ndarray | None = None
        self.memo: dict[tuple, float] = {}  # execution key -> coverage as executed (Q14)
        self.executed_floor = 0.0  # (X10)

    def executed(self, result: ScheduleResult) -> float:
        """A result's coverage as ZTF's scheduler executes its published plan's queues (Q14), remembered."""
        from ..as_executed import keyed_coverage_as_executed

        key, value = keyed_coverage_as_executed(self.problem, result, self.memo)
        if key is not None:
            self.memo[key] = value
        return value

    def published(self, result: ScheduleResult) -> tuple[float, float]:
        """(coverage, expected detections) of a result as its plan will be published."""
        problem = self.problem
        kept = drop_low_gain(result, problem.footprints, problem.prob, problem.config.min_gain).observations
        cov = problem.footprints.coverage({o.field_id for o in kept}, problem.prob)
        return cov, plan_expected_detections(problem, self.skymap, kept, self.kilonova, self.depth)

    def left_s(self) -> float:
        """Solve time left: the budget, less the time spent and the time to time and score a solution."""
        return self.budget - self.problem.clock.since(self.started) - self.post_s  # (A1)

    def solve_grids(self, coverage: ScheduleResult, floor: float, accept_floor: float, best: tuple
                    ) -> tuple[tuple, list[dict]]:
        """Solve the grids in turn from ``coverage``'s plan; (the best (e, obs, res, c), per-grid runs).

        ``floor`` is the model's (X6, on the grid's coverage), ``accept_floor`` the least published coverage of
        a plan the stage may return (``coverage_floor``: at least ``floor``).
        """
        from ..blocks.schedule import shortlist_footprints
        from ..slots.schedule import slot_portfolio, slot_rows

        problem = self.problem
        start_first: dict[int, float] = {}
        for o in coverage.observations:
            start_first[o.field_id] = min(o.start, start_first.get(o.field_id, np.inf))
        rows = slot_rows(problem, np.asarray(list(start_first), np.int64))
        self.fp = shortlist_footprints(problem.footprints, rows)
        self.cells = merge_cells(self.fp, problem.prob)
        self.rows, self.floor, self.accept_floor = rows, floor, accept_floor
        self.backend = resolve_backend(problem.config.milp_backend)
        field_of_row = {int(problem.field_ids[r]): f for f, r in enumerate(rows)}
        self.start_f = {field_of_row[fid]: t for fid, t in start_first.items() if fid in field_of_row}
        self.start_exp = {f: problem.config.exposure_s for f in self.start_f}
        self.field_of_row = field_of_row
        grids = [(g, False) for g in slot_portfolio(problem, rows)]
        grids.sort(key=lambda g: g[0].name != coverage.grid)  # the coverage plan's own grid first
        self.menu = bool(problem.config.exposure_menu_s)
        if self.menu:  # the fixed exposure's own grid, then the menu grids (their own first), each from the best so far
            own = _grid_name(coverage.grid, problem.config)
            menu = sorted(menu_portfolio(problem, rows), key=lambda g: _grid_name(g.name, problem.config) != own)
            grids = grids[:1] + [(g, True) for g in menu]
        runs: list[dict] = []
        for i, (grid, on_menu) in enumerate(grids):
            if self.should_stop is not None and self.should_stop():
                break
            if MAX_GRIDS is not None and i >= MAX_GRIDS:
                runs.append({"grid": grid.name, "status": "not tried"})
                break
            if self.left_s() < MIN_SOLVE_S:
                runs.append({"grid": grid.name, "status": "no time left"})
                break
            run, found, stop = self._solve_grid(grid, i, len(grids), on_menu)
            if run is not None:
                runs.append(run)
            if (found is not None and is_preferred(found[3], found[0], best[3], best[0], problem.config.min_gain,
                                                   "detection", coverage_floor=accept_floor)
                    and self._executes_above_floor(found, run)):
                best = found  # R2, or R3: a tie in expected detections and more coverage
                if self.menu:
                    self._start_from(best[1])
            if stop:
                break
        return best, runs

    def _executes_above_floor(self, found: tuple, run: dict | None) -> bool:
        """(X10) the candidate's queues, as ZTF's scheduler executes them, cover at least the executed floor."""
        executed = self.executed(ScheduleResult(tuple(found[1]), "detection", found[2].status))
        ok = executed >= self.executed_floor - 1e-9
        if run is not None:
            run["coverage_as_executed"], run["above_executed_floor"] = round(executed, 6), ok
        return ok

    def _start_from(self, observations) -> None:
        """The next grids start from these exposures: each field's first start and its exposure."""
        start: dict[int, float] = {}
        exp: dict[int, float] = {}
        for o in observations:
            f = self.field_of_row.get(o.field_id)
            if f is not None and o.start < start.get(f, np.inf):
                start[f], exp[f] = o.start, o.exposure_s
        self.start_f, self.start_exp = start, exp

    def _solve_grid(self, grid, i: int, n_grids: int, on_menu: bool = False
                    ) -> tuple[dict | None, tuple | None, bool]:
        """Solve one grid: (its run record or None, its (e, obs, res, c) when above the floor, stop after it)."""
        from ..slots.schedule import map_start, time_slot_plan

        problem, cfg = self.problem, self.problem.config
        if on_menu:
            inst = menu_instance(problem, self.rows, grid, self.cells)
        else:
            inst = slot_instance(problem, self.rows, grid, cells=self.cells)
        if inst.n_pairs == 0:
            return None, None, False
        problem.clock.step("reach", inst.n_pairs)  # (A3)
        reach = pair_reach(problem, inst, self.kilonova, self.skymap.event_time, self.depth)
        if self.levels is None:  # placed once, on the first grid's reaches, for every grid
            r_max = float(reach.max(initial=0.0))
            # up to the longest menu exposure's reach: (D1), (X2) at equal sky; (D2) only shortens it
            if self.menu and not on_menu:
                r_max *= max(float(max(cfg.exposure_menu_s)) / cfg.exposure_s, 1.0) ** 0.25
            self.levels = distance_levels(self.skymap, np.unique(self.fp.indices), r_max, cfg.detection_levels)
            if self.levels.size == 0:
                return None, None, True
            self.W = level_weights(self.skymap, self.fp, self.cells, self.levels)
        plev = pair_levels(reach, self.levels)
        n_offered = inst.n_pairs
        if on_menu:  # a longer exposure that reaches no farther than a shorter one at the same start only costs time
            keep = ~dominated_pairs(inst, plev)
            inst, plev, reach = inst.subset(keep), plev[keep], reach[keep]
        dm = build_detection_model(inst, self.W, plev, cfg.penalty, cfg.detection_coverage_weight,
                                   coverage_floor=self.floor)
        model = dm.model
        x0 = None
        if self.start_f:
            pairs = (map_start_menu(inst, self.start_f, self.start_exp) if on_menu
                     else map_start(inst, self.start_f))
            if on_menu:  # (X9) the seed, filled or replaced greedily by gain per position held
                pairs = menu_start_pairs(inst, plev, self.W, cfg.detection_coverage_weight, cfg.penalty, pairs,
                                         self.floor)
            if pairs.size and inst.cells.weight[_covered_cells(inst, pairs)].sum() >= self.floor:
                x0 = detection_start_vector(dm, pairs)  # a start below the floor (X6) would be refused
        left = self.left_s()
        if left < MIN_SOLVE_S:
            return {"grid": grid.name, "status": "no time left"}, None, True
        if self.menu:  # the fixed grid a share, the first menu grid most of the rest
            limit = left * MENU_FIXED_SHARE if i == 0 else left * FIRST_GRID_SHARE if i == 1 else left / (n_grids - i)
        else:
            limit = left * FIRST_GRID_SHARE if i == 0 else left / max(n_grids - i, 1)
        limit = max(limit, min(left, MIN_SOLVE_S))
        # (V6) stop once the bound proves no solution beats the incumbent by min_gain
        res = solve_milp(model.milp, self.backend, limit, cfg.mip_gap, cfg.threads, self.should_stop, start=x0,
                         abs_gap=cfg.min_gain, clock=problem.clock)
        if not res.has_solution:
            return {"grid": grid.name, "status": res.status}, None, False
        t_post = problem.clock.mark()
        obs, dropped, _ = time_slot_plan(problem, model, res.x)
        c, e = self.published(ScheduleResult(tuple(obs), "detection", res.status))
        self.post_s = max(self.post_s, problem.clock.since(t_post))
        ok = c >= self.accept_floor - 1e-9
        run = {"grid": grid.name, "status": res.status, "levels": int(self.levels.size), "pairs": inst.n_pairs,
               "objective": res.objective, "bound": res.bound, "expected_detections": e, "coverage": c,
               "above_floor": ok, "dropped": len(dropped), "runtime_s": round(res.runtime_s, 3),
               "last_gain_s": _last_gain_s(res.progress, cfg.min_gain)}
        if on_menu:
            run["pairs_offered"] = n_offered
            run["exposures"] = _exposure_counts(obs)
        return run, ((e, obs, res, c) if ok else None), False


def _last_gain_s(trace: list[tuple[float, float, float]], gain: float) -> float | None:
    """When (s into the solve) the incumbent last improved by more than ``gain``; None without an incumbent."""
    at, best = None, -np.inf
    for t, objective, _ in trace:
        if objective > best + gain:
            at, best = round(t, 3), objective
    return at


def _grid_name(name: str | None, config) -> str | None:
    """The portfolio's ``n<k>/<phase>`` a grid stands for (a menu grid of n' positions stands for its n)."""
    if not name or not name.startswith("n") or "/" not in name:
        return name
    n_txt, phase = name[1:].split("/", 1)
    if not n_txt.isdigit():
        return name
    for n in config.slot_positions:
        if int(n_txt) in (int(n), menu_positions(int(n), config)):
            return f"n{int(n)}/{phase}"
    return name


def _exposure_counts(obs: list[Observation]) -> dict[str, int]:
    """Fields per exposure time of a plan, e.g. ``{"60": 12, "300": 4}``."""
    per_field = {o.field_id: o.exposure_s for o in obs}
    vals, counts = np.unique(np.array(list(per_field.values()), float), return_counts=True)
    return {f"{v:g}": int(c) for v, c in zip(vals, counts)}


def _covered_cells(inst: SlotInstance, pairs: np.ndarray) -> np.ndarray:
    """Mask of the cells covered by the fields of some pairs."""
    z = np.zeros(inst.n_fields, bool)
    z[inst.pair_field[np.asarray(pairs, np.int64)]] = True
    cell_of = np.repeat(np.arange(inst.cells.n_cells), np.diff(inst.cells.indptr))
    hit = np.zeros(inst.cells.n_cells, bool)
    np.logical_or.at(hit, cell_of, z[inst.cells.fields])
    return hit
