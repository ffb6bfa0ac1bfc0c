"""The detection objective's model on the slot grid: reaches, distance levels, level weights, X2-X6.

On the slot grid (:mod:`..slots.model`) every eligible pair ``k = (field f, slot s)`` has a known time, filter pair and
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

The stage that solves it, times and scores its plans is
:mod:`.stage`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from astropy.time import Time, TimeDelta

from ...problem import PlanningProblem
from ...sky.cells import Cells
from ...sky.footprints import Footprints
from ...sky.skymap import SkyMap
from ...source.depth import ZTF_DEPTH, DepthModel, limiting_magnitude, sky_conditions
from ...source.detection import distance_cdf, reach_mpc
from ...source.kilonova import Kilonova
from ..milp.rows import Columns, RowBuilder
from ..slots.model import SlotInstance, SlotModel, build_slot_model, slot_model_rows, start_vector
from ..milp.solvers import MilpModel

__all__ = ["pair_reach", "distance_levels", "pair_levels", "cell_of_pixels", "level_weights", "DetectionModel",
           "build_detection_model", "detection_start_vector"]


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
        cond = sky_conditions(ra, dec, problem.start + TimeDelta(mid, format="sec"), depth.location)
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
