"""The detection objective on the slot model: plan for the kilonova found, not only the area covered.

Coverage counts a cell once any field holding it is observed, however
shallow or late the exposure.  The detection objective counts what the
evaluation counts: the probability that the source, at the cell's distance
posterior, is brighter than the limit of the best exposure covering it
(:mod:`.detection`, equation X1).  On the slot grid (:mod:`.slots`) every
eligible pair ``k = (field f, slot s)`` has a known time, filter pair and
sky, hence a *reach* ``r_k`` (Mpc, equation X2: the larger of its two
exposures').  The reaches are rounded down to ``L`` distance levels
``0 < r_1 < ... < r_L`` and the model gains, per level ``l``
(``docs/design/detection.md``):

- ``u_fl`` in [0, 1]: field f is observed in a slot reaching level l,
  (X3) ``u_fl - Σ_{k ∋ f, lev(k) >= l} x_k = 0``;
- ``v_cl`` in [0, 1]: cell c is seen out to ``r_l``,
  (X4) ``v_cl - Σ_{f ∋ c} u_fl <= 0``;
- objective (X5) ``Σ_cl W_cl v_cl + λ Σ_c w_c y_c - p Σ_f z_f`` with
  ``W_cl = Σ_{pixels i of c} prob_i (F_i(r_l) - F_i(r_{l-1}))``, the
  probability of the cell's sources lying between two levels, and a small
  coverage term (``λ = detection_coverage_weight``) that breaks ties
  towards more probability;
- (X6) coverage floor ``Σ_c w_c y_c >= (1 - ε) C₀``: the plan covers at
  least ``1 - ε`` (``ε = detection_max_coverage_loss``) of what the
  coverage plan it starts from covers (``C₀``, as published).

Since every ``W_cl >= 0`` the optimum sets ``v_cl = 1`` for every level up
to the best reached one, so ``Σ_l W_cl v_cl`` is the cell's detection
probability at its best covering slot (rounded down to a level).

The stage starts from a coverage plan (mapped onto each grid, the solver's
first incumbent), solves the portfolio's grids within its own budget,
times every solution with the real overheads (:func:`.slot_schedule.time_slot_plan`)
and scores the executable plans exactly with (X1).  It returns the coverage
plan itself unless a detection plan, as it will be published (after the
real timing and the least-gain rule), has more expected detections *and*
still respects the floor (X6), or, when the expected detections tie
(closer than ``config.min_gain``, e.g. both ~0 for a source too far for the
light curve), covers more by ``min_gain`` (:mod:`..preference`, R1-R3): it
never publishes fewer detections than the plan it started from (beyond the
margin), nor loses more than ``ε`` of its coverage, nor keeps a plan over
one with as many expected detections and more coverage.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np
from astropy.time import Time, TimeDelta

from ..sequences import require_pair
from ..sky.cells import Cells, merge_cells
from ..source.depth import ZTF_DEPTH, DepthModel, limiting_magnitude, sky_conditions
from ..source.detection import distance_cdf, reach_mpc
from .detection_ceiling import detection_ceiling
from .gain import drop_low_gain
from ..preference import is_preferred
from ..source.kilonova import Kilonova, load_kilonova
from ..plan.document import Observation, Plan, PlanMetrics
from ..sky.footprints import Footprints
from ..problem import DetectionReport, PlanningProblem, ScheduleResult, StopCheck
from ..sky.skymap import SkyMap
from .exposure_menu import (dominated_pairs, map_start_menu, menu_instance, menu_portfolio, menu_positions,
                            menu_start_pairs)
from .rows import Columns, RowBuilder
from .slots import SlotInstance, SlotModel, build_slot_model, slot_instance, slot_model_rows, start_vector
from .solvers import MilpModel, resolve_backend, solve_milp

__all__ = ["pair_reach", "distance_levels", "pair_levels", "level_weights", "DetectionModel", "build_detection_model",
           "detection_start_vector", "plan_expected_detections", "detection_stage"]

log = logging.getLogger(__name__)

#: Least solve time (s) worth starting a grid with; below it the stage stops.
MIN_SOLVE_S = 0.3

#: Share of the stage's time left given to the first grid (the coverage plan's own, warm-started):
#: on 12 shared maps 0.9 found more than 0.5 (solving one grid well beats a wide, shallow portfolio).
FIRST_GRID_SHARE = 0.9

#: With an exposure menu: share of the stage's time left given to the fixed exposure's own grid, solved
#: first (small, fast); the first menu grid, warm-started from the best plan so far, gets FIRST_GRID_SHARE
#: of what is left after it.
MENU_FIXED_SHARE = 0.3


def pair_reach(problem: PlanningProblem, inst: SlotInstance, kilonova: Kilonova, merger_time: Time,
               depth: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """(K,) reach (Mpc) of each eligible pair: the deeper of its two exposures (X2).

    Each exposure is taken at the slot's fixed time, at mid-exposure, with
    the field centre's airmass, Moon and twilight, and lasts the pair's own
    exposure (``inst.pair_exposure`` on a menu grid, else ``exposure_s``).
    """
    cfg = problem.config
    e = inst.exposures(cfg.exposure_s)  # each pair's own exposure (a menu's, or exposure_s)
    rows = inst.rows[inst.pair_field]
    ra, dec = problem.ra[rows], problem.dec[rows]
    offset_d = float((Time(problem.start) - Time(merger_time)).to_value("day"))
    best = np.zeros(inst.n_pairs)
    for band, t in zip(cfg.filters, (inst.grid.t1, inst.grid.t2)):
        mid = t[inst.pair_slot] + 0.5 * e
        cond = sky_conditions(ra, dec, problem.start + TimeDelta(mid, format="sec"))
        m5 = limiting_magnitude(np.full(inst.n_pairs, band), e, cond, depth)
        absmag = kilonova.absolute_mag(band, offset_d + mid / 86400.0)
        best = np.maximum(best, reach_mpc(m5, absmag))
    return best


def distance_levels(skymap: SkyMap, pixels: np.ndarray, r_max: float, n_levels: int,
                    n_samples: int = 4000, seed: int = 0) -> np.ndarray:
    """Up to ``n_levels`` increasing distance levels (Mpc) placed where the sources are.

    The levels split the probability of the sources closer than ``r_max``
    (the farthest reach of any pair) into equal parts: quantiles of
    distances drawn from the position-weighted distance posterior of
    ``pixels`` (the shortlisted fields' pixels), with ``r_max`` the top
    level.  Rounding a pair's reach down to a level then loses at most
    ``1 / n_levels`` of the reachable probability of a cell (on average half
    of it).

    Parameters
    ----------
    skymap : SkyMap
        With distance layers.
    pixels : numpy.ndarray
        Pixels the plan can cover.
    r_max : float
        Largest reach (Mpc).
    n_levels : int
        L.
    n_samples : int
        Distances drawn to place the levels.
    seed : int
        Seed of the draw (the levels are reproducible).
    """
    from ligo.skymap.distance import conditional_ppf, parameters_to_moments

    if not r_max > 0:
        return np.zeros(0)
    pixels = np.asarray(pixels, np.int64)
    w = skymap.prob[pixels]
    rng = np.random.default_rng(seed)
    pick = pixels[rng.choice(pixels.size, size=n_samples, p=w / w.sum())] if w.sum() > 0 else pixels[:0]
    mu, sigma = skymap.distmu[pick], skymap.distsigma[pick]
    ok = np.isfinite(mu) & np.isfinite(sigma) & (sigma > 0)
    with np.errstate(all="ignore"):
        norm = parameters_to_moments(mu[ok], sigma[ok])[2]
        r = conditional_ppf(rng.random(int(ok.sum())), mu[ok], sigma[ok], norm)
    r = r[np.isfinite(r) & (r > 0) & (r < r_max)]
    inner = np.quantile(r, np.arange(1, n_levels) / n_levels) if r.size >= n_levels else np.zeros(0)
    return np.unique(np.concatenate([inner[inner > 0], [r_max]]))


def pair_levels(reach: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """(K,) number of levels each pair reaches (``r_l <= reach``): 0..L."""
    return np.searchsorted(levels, np.asarray(reach, float) * (1 + 1e-12), side="right")


def _field_keys(n: int) -> np.ndarray:
    rng = np.random.default_rng(0xDE7EC7)
    return rng.integers(1, 2**63 - 1, size=n, dtype=np.uint64)


def cell_of_pixels(footprints: Footprints, cells: Cells, prob: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (probability > 0, in some field) and the merged cell holding each.

    The membership of a pixel and of a cell are both hashed as the XOR of
    random 64-bit keys of their fields, and pixels are matched to cells by
    hash (vectorised; a failed match raises, it is never guessed).
    """
    counts = np.diff(footprints.indptr)
    rows = np.repeat(np.arange(counts.size, dtype=np.int64), counts)
    pix = np.asarray(footprints.indices, np.int64)
    keep = prob[pix] > 0
    pix, rows = pix[keep], rows[keep]
    keys = _field_keys(counts.size)
    upix, inv = np.unique(pix, return_inverse=True)
    h_pix = np.zeros(upix.size, np.uint64)
    np.bitwise_xor.at(h_pix, inv, keys[rows])
    h_cell = np.zeros(cells.n_cells, np.uint64)
    cell_idx = np.repeat(np.arange(cells.n_cells), np.diff(cells.indptr))
    np.bitwise_xor.at(h_cell, cell_idx, keys[cells.fields])
    order = np.argsort(h_cell)
    pos = np.minimum(np.searchsorted(h_cell[order], h_pix), max(cells.n_cells - 1, 0))
    cell = order[pos]
    if cells.n_cells == 0 or not np.array_equal(h_cell[cell], h_pix):
        raise RuntimeError("pixel memberships do not match the merged cells")
    return upix, cell


def level_weights(skymap: SkyMap, footprints: Footprints, cells: Cells, levels: np.ndarray) -> np.ndarray:
    """(C, L) ``W_cl``: probability of each cell's sources between levels l-1 and l (X5)."""
    upix, cell = cell_of_pixels(footprints, cells, skymap.prob)
    L = levels.size
    F = np.zeros((upix.size, L + 1))
    for j, r in enumerate(levels.tolist()):  # a loop over levels (L ~ 8), not pixels
        F[:, j + 1] = distance_cdf(skymap, upix, np.full(upix.size, r))
    inc = np.maximum(np.diff(F, axis=1), 0.0) * skymap.prob[upix][:, None]
    W = np.zeros((cells.n_cells, L))
    for j in range(L):
        W[:, j] = np.bincount(cell, weights=inc[:, j], minlength=cells.n_cells)
    return W


@dataclass(frozen=True)
class DetectionModel:
    """The slot model with the detection blocks, and what it was built from.

    Attributes
    ----------
    model : SlotModel
        Variables ``[x (K) | z (F) | y (C) | u (F*L) | v (C*L)]``; ``u_fl`` at
        ``off_u + f*L + l`` and ``v_cl`` at ``off_v + c*L + l``.
    base : SlotModel
        The coverage slot model (S0-S3) it extends.
    pair_level : numpy.ndarray
        (K,) levels reached by each pair.
    n_levels : int
        L.
    """

    model: SlotModel
    base: SlotModel
    pair_level: np.ndarray
    n_levels: int

    @property
    def off_u(self) -> int:
        """Offset of the field-level variables u."""
        return self.base.milp.n_vars

    @property
    def off_v(self) -> int:
        """Offset of the cell-level variables v."""
        return self.off_u + self.base.instance.n_fields * self.n_levels


def build_detection_model(inst: SlotInstance, W: np.ndarray, pair_level: np.ndarray, penalty: float = 0.0,
                          coverage_weight: float = 0.05, coverage_floor: float | None = None) -> DetectionModel:
    """The slot model (S1-S3) with the detection blocks (X3-X6) appended.

    Parameters
    ----------
    inst : SlotInstance
        Grid, cells and eligible pairs.
    W : numpy.ndarray
        (C, L) level weights (:func:`level_weights`).
    pair_level : numpy.ndarray
        (K,) levels each pair reaches (:func:`pair_levels`).
    penalty : float
        p per observed field.
    coverage_weight : float
        λ of the coverage tie-break term.
    coverage_floor : float, optional
        (X6) least coverage ``Σ_c w_c y_c`` (0-1) of the solution; None: no floor.

    Returns
    -------
    DetectionModel
    """
    base = build_slot_model(inst, penalty)
    K, F, C = inst.n_pairs, inst.n_fields, inst.cells.n_cells
    L = W.shape[1]
    cols = Columns()
    x, z, y = cols.family("x", K), cols.family("z", F), cols.family("y", C)
    u, v = cols.family("u", F * L), cols.family("v", C * L)  # u[f L + l], v[c L + l]
    n0, n = base.milp.n_vars, cols.n
    rows = RowBuilder()
    slot_model_rows(rows, inst, x, z, y)  # (S1-S3) on the same columns as the slot model's
    # (X3) u_fl - Σ_{k ∋ f, lev(k) >= l} x_k = 0
    kk, ll = np.nonzero(np.arange(L)[None, :] < pair_level[:, None])  # pair k reaches level l (0-based)
    rows.block("X3 field level", F * L,
               [(np.arange(F * L), u.columns, 1.0), (inst.pair_field[kk] * L + ll, x[kk], -1.0)], 0.0, 0.0)
    # (X4) v_cl - Σ_{f ∋ c} u_fl <= 0
    cell_of = np.repeat(np.arange(C), np.diff(inst.cells.indptr))
    cf_c = np.repeat(cell_of, L)
    cf_f = np.repeat(inst.cells.fields, L)
    cf_l = np.tile(np.arange(L), cell_of.size)
    rows.block("X4 cell level", C * L,
               [(np.arange(C * L), v.columns, 1.0), (cf_c * L + cf_l, u[cf_f * L + cf_l], -1.0)], -np.inf, 0.0)
    if coverage_floor is not None:  # (X6) Σ_c w_c y_c >= floor
        rows.block("X6 coverage floor", 1, [(np.zeros(C, np.int64), y.columns, np.asarray(inst.cells.weight, float))],
                   float(coverage_floor), np.inf)
    A, row_lo, row_hi = rows.matrix(n)
    # (X5) Σ W v + λ Σ w y - p Σ z
    c = np.zeros(n)
    c[:n0] = base.milp.c
    c[y.columns] *= coverage_weight
    c[v.columns] = W.ravel()
    integer = np.concatenate([base.milp.integer, np.zeros(n - n0, bool)])
    milp = MilpModel(c, A, row_lo, row_hi, np.zeros(n), np.ones(n), integer, rows.blocks(), cols.families())
    return DetectionModel(SlotModel(milp, inst), base, np.asarray(pair_level, np.int64), L)


def detection_start_vector(dm: DetectionModel, pairs: np.ndarray) -> np.ndarray:
    """A full solution vector of the detection model choosing the given pairs (x, z, y, u, v)."""
    inst = dm.base.instance
    F, C, L = inst.n_fields, inst.cells.n_cells, dm.n_levels
    x = np.zeros(dm.model.milp.n_vars)
    x[:dm.off_u] = start_vector(dm.base, pairs)
    u = np.zeros((F, L))
    p = np.asarray(pairs, np.int64)
    for lvl in range(L):  # a loop over levels, not pairs
        u[inst.pair_field[p[dm.pair_level[p] > lvl]], lvl] = 1.0
    v = np.zeros((C, L))
    cell_of = np.repeat(np.arange(C), np.diff(inst.cells.indptr))
    np.maximum.at(v, cell_of, u[inst.cells.fields])
    x[dm.off_u:dm.off_v] = u.ravel()
    x[dm.off_v:] = v.ravel()
    return x


def plan_expected_detections(problem: PlanningProblem, skymap: SkyMap, observations: tuple[Observation, ...] | list,
                             kilonova: Kilonova, depth: DepthModel = ZTF_DEPTH) -> float:
    """Exact expected detections (X1) of scheduled exposures."""
    from ..source.detection import expected_detections

    plan = Plan("candidate", problem.start, problem.start + TimeDelta(problem.horizon_s, format="sec"),
                tuple(observations), PlanMetrics(0.0, "", "", None, 0.0, 0, len(observations)))
    e = expected_detections(plan, skymap, problem.footprints, kilonova, skymap.event_time, depth)
    return 0.0 if e is None else e


def detection_stage(problem: PlanningProblem, skymap: SkyMap, coverage: ScheduleResult,
                    should_stop: StopCheck | None = None, kilonova: Kilonova | None = None,
                    depth: DepthModel = ZTF_DEPTH, time_limit_s: float | None = None) -> ScheduleResult:
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
        Wall-clock budget (s) of the whole stage (scoring, models, solves,
        timing); default ``config.detection_time_limit_s``.  A grid is only
        started when at least :data:`MIN_SOLVE_S` of solve time is left
        after the time its solution will take to time and score.

    Returns
    -------
    ScheduleResult
        The detection plan when, as it will be published (after the
        least-gain rule), it has more expected detections (X1) than
        ``coverage`` by ``config.min_gain`` and covers at least ``(1 - ε)``
        of ``coverage``'s published coverage (X6), or ties on expected
        detections and covers more by ``min_gain`` (R1-R3); else
        ``coverage`` itself.  ``expected_detections`` (and
        ``expected_detections_lightcurve``) hold the returned plan's score,
        ``detection`` (:class:`~..problem.DetectionReport`) the choice, the
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
    stage = _Stage(problem, skymap, kilonova, depth, should_stop, budget, t_wall)
    t_score = time.perf_counter()
    c_cov, e_cov = stage.published(coverage)
    stage.post_s = time.perf_counter() - t_score + 0.1  # time to time and score one solution (updated as measured)
    floor = (1.0 - cfg.detection_max_coverage_loss) * c_cov
    lightcurve = cfg.detection_lightcurve if own_kilonova else None
    ceiling = detection_ceiling(problem, skymap, kilonova, depth)
    if ceiling < e_cov + cfg.min_gain:  # (X7) no plan detects min_gain more: the answer cannot change
        log.info("detection objective skipped: no plan can have more than %.4f expected detections, the coverage "
                 "plan has %.4f", ceiling, e_cov)
        return _kept_coverage(coverage, t_wall, "coverage (at the detection ceiling)", budget,
                              (e_cov, floor, lightcurve), ())
    best, runs = stage.solve_grids(coverage, floor, (e_cov, None, None, c_cov))
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
                 should_stop: StopCheck | None, budget: float, t_wall: float) -> None:
        self.problem, self.skymap, self.kilonova, self.depth = problem, skymap, kilonova, depth
        self.should_stop, self.budget, self.t_wall = should_stop, budget, t_wall
        self.post_s = 0.1
        self.levels: np.ndarray | None = None
        self.W: np.ndarray | None = None

    def published(self, result: ScheduleResult) -> tuple[float, float]:
        """(coverage, expected detections) of a result as its plan will be published."""
        problem = self.problem
        kept = drop_low_gain(result, problem.footprints, problem.prob, problem.config.min_gain).observations
        cov = problem.footprints.coverage({o.field_id for o in kept}, problem.prob)
        return cov, plan_expected_detections(problem, self.skymap, kept, self.kilonova, self.depth)

    def left_s(self) -> float:
        """Solve time left: the budget, less the time spent and the time to time and score a solution."""
        return self.budget - (time.perf_counter() - self.t_wall) - self.post_s

    def solve_grids(self, coverage: ScheduleResult, floor: float, best: tuple) -> tuple[tuple, list[dict]]:
        """Solve the grids in turn from ``coverage``'s plan; (the best (e, obs, res, c), per-grid runs)."""
        from .block_schedule import shortlist_footprints
        from .slot_schedule import slot_portfolio, slot_rows

        problem = self.problem
        start_first: dict[int, float] = {}
        for o in coverage.observations:
            start_first[o.field_id] = min(o.start, start_first.get(o.field_id, np.inf))
        rows = slot_rows(problem, np.asarray(list(start_first), np.int64))
        self.fp = shortlist_footprints(problem.footprints, rows)
        self.cells = merge_cells(self.fp, problem.prob)
        self.rows, self.floor = rows, floor
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
            if self.left_s() < MIN_SOLVE_S:
                runs.append({"grid": grid.name, "status": "no time left"})
                break
            run, found, stop = self._solve_grid(grid, i, len(grids), on_menu)
            if run is not None:
                runs.append(run)
            if found is not None and is_preferred(found[3], found[0], best[3], best[0], problem.config.min_gain,
                                                  "detection", coverage_floor=floor):
                best = found  # R2, or R3: a tie in expected detections and more coverage
                if self.menu:
                    self._start_from(best[1])
            if stop:
                break
        return best, runs

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
        from .slot_schedule import map_start, time_slot_plan

        problem, cfg = self.problem, self.problem.config
        if on_menu:
            inst = menu_instance(problem, self.rows, grid, self.cells)
        else:
            inst = slot_instance(problem, self.rows, grid, cells=self.cells)
        if inst.n_pairs == 0:
            return None, None, False
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
        res = solve_milp(model.milp, self.backend, limit, cfg.mip_gap, cfg.threads, self.should_stop, start=x0)
        if not res.has_solution:
            return {"grid": grid.name, "status": res.status}, None, False
        t_post = time.perf_counter()
        obs, dropped, _ = time_slot_plan(problem, model, res.x)
        c, e = self.published(ScheduleResult(tuple(obs), "detection", res.status))
        self.post_s = max(self.post_s, time.perf_counter() - t_post)
        ok = c >= self.floor - 1e-9
        run = {"grid": grid.name, "status": res.status, "levels": int(self.levels.size), "pairs": inst.n_pairs,
               "objective": res.objective, "bound": res.bound, "expected_detections": e, "coverage": c,
               "above_floor": ok, "dropped": len(dropped), "runtime_s": round(res.runtime_s, 3)}
        if on_menu:
            run["pairs_offered"] = n_offered
            run["exposures"] = _exposure_counts(obs)
        return run, ((e, obs, res, c) if ok else None), False


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
