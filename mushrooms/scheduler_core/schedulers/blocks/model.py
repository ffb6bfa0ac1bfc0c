"""The block-division MILP (paper appendix A, with the fixes to its text).

Equations B0-B11 of ``docs/design/milp.md`` (B1-B7 in the appendix's order;
the fixes to the appendix are listed there); each constraint block below
carries its number.

Times are seconds since the horizon start.  A *candidate* is one
(shortlisted field, observability window) pair: a field with two windows
over the horizon has two candidates, and at most one of them is used.

Variables (all in one vector, see :class:`BlockModel` for the layout)

- ``B[i, k]`` binary: candidate k is observed in block i;
- ``x[j]`` in [0, 1]: field j is observed (``x_j = Σ_i Σ_{k of j} B[i, k]``,
  so a field sits in at most one block, in one of its windows);
- ``y[c]`` in [0, 1]: cell c is covered (continuous: with integral ``B`` the
  optimum puts every ``y`` at 0 or 1, as the appendix's binary would);
- ``U[i]`` binary: block i is used;
- ``t[i]`` in [0, H]: block i's start; ``d[i]`` >= 0: block i's duration.

Maximise ``Σ_c w_c y_c − p Σ_{i,k} B[i, k]`` subject to

- ``y_c <= Σ_{j ∋ c} x_j`` (the pixel constraint over the fields containing
  the cell, not over blocks as the appendix misprints);
- ``B[i, k] <= U[i]``; ``Σ_k B[i, k] >= b_size U[i]`` (b_size capped by the
  number of shortlisted fields); ``U[i] <= U[i-1]``;
- ``d[i] >= 2 s n_i + (t_filt + e_i) U_i`` and
  ``d[i] >= s n_i + (cadence + e_i) U_i`` with ``s = t_exp + t_slew`` and
  ``n_i = Σ_k B[i, k]``: one pass in each filter and a filter change, or,
  for a block shorter than b_size, the wait that keeps the cadence.  Unused
  blocks cost nothing (no filter change);
- ``t[i] >= T_s[k] B[i, k]`` and ``t[i] + d[i] <= T_e[k] + (H − T_e[k])(1 − B[i, k])``:
  the whole block lies inside the window of each of its candidates;
- ``t[i] >= t[i-1] + d[i-1] + (t_filt + g_{i-1}) U_i``: a block starts after
  the previous one *ends* (its own size), after the filter change back to
  the first filter, plus the gap parameter g;
- ``t[i] + d[i] <= H``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...sky.cells import Cells
from ...config import PlanningConfig
from ..milp.rows import Columns, RowBuilder
from ..milp.solvers import MilpModel

__all__ = ["BlockParams", "Candidates", "BlockModel", "block_size", "build_block_model", "decode_blocks",
           "DecodedBlock", "heuristic_start", "earliest_block_starts"]


def block_size(config: PlanningConfig) -> int:
    """Least number of fields in a block for the cadence to hold without waiting.

    The second-filter visit of a field comes one pass of the block plus a
    filter change after its first visit, so ``n (t_exp + t_slew) + t_filt >=
    cadence`` gives ``b_size = ceil((cadence − t_filt) / (t_exp + t_slew))``
    (at least 1).  A positive ``config.min_block_size`` replaces the rule.

    Parameters
    ----------
    config : PlanningConfig
        Uses ``cadence_s``, ``filter_change_s``, ``exposure_s``,
        ``slew_estimate_s`` (all s).

    Returns
    -------
    int
    """
    if config.min_block_size > 0:
        return int(config.min_block_size)
    return cadence_block_size(config)


def cadence_block_size(config: PlanningConfig) -> int:
    """The cadence rule alone: ``ceil((cadence − t_filt) / (t_exp + t_slew))``, at least 1 (6 at 300 s, 9 at 180 s)."""
    per_visit = config.exposure_s + config.slew_estimate_s
    return max(1, int(math.ceil((config.cadence_s - config.filter_change_s) / per_visit - 1e-9)))


@dataclass(frozen=True)
class BlockParams:
    """Timing parameters of the block model (s).

    Attributes
    ----------
    n_blocks : int
        b_max.
    b_size : int
        Least fields per used block.
    exposure_s, slew_s, filter_change_s, cadence_s, horizon_s : float
        t_exp, t_slew (estimate, readout included), t_filt, cadence, H.
    penalty : float
        p, per field-block assignment.
    gaps : numpy.ndarray
        (n_blocks - 1,) g_i: extra time between block i and i+1.
    extra : numpy.ndarray
        (n_blocks,) extra duration of block i (post-processing retries).
    """

    n_blocks: int
    b_size: int
    exposure_s: float
    slew_s: float
    filter_change_s: float
    cadence_s: float
    horizon_s: float
    penalty: float
    gaps: np.ndarray
    extra: np.ndarray

    @classmethod
    def from_config(cls, config: PlanningConfig, n_blocks: int | None = None) -> "BlockParams":
        """Parameters from a :class:`PlanningConfig` (gaps all ``block_gap_s``)."""
        nb = config.n_blocks_max if n_blocks is None else n_blocks
        return cls(
            n_blocks=nb, b_size=block_size(config), exposure_s=config.exposure_s,
            slew_s=config.slew_estimate_s, filter_change_s=config.filter_change_s,
            cadence_s=config.cadence_s, horizon_s=config.horizon_s, penalty=config.penalty,
            gaps=np.full(max(nb - 1, 0), float(config.block_gap_s)), extra=np.zeros(nb),
        )

    @property
    def per_visit_s(self) -> float:
        """s = t_exp + t_slew."""
        return self.exposure_s + self.slew_s

    def least_duration_s(self, n_fields: int) -> float:
        """Duration (s) the model gives a block of ``n_fields`` fields (no extra)."""
        s = self.per_visit_s
        return max(2 * s * n_fields + self.filter_change_s, s * n_fields + self.cadence_s)


@dataclass(frozen=True)
class Candidates:
    """(field, window) pairs the model may schedule.

    Attributes
    ----------
    field : numpy.ndarray
        (K,) shortlisted-field index (row of the shortlist footprints).
    start, end : numpy.ndarray
        (K,) window bounds (s), clipped to the horizon.
    """

    field: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return int(self.field.size)


@dataclass(frozen=True)
class BlockModel:
    """The assembled MILP and where each variable family sits in ``x``.

    Attributes
    ----------
    milp : MilpModel
    n_blocks, n_candidates, n_fields, n_cells : int
    """

    milp: MilpModel
    n_blocks: int
    n_candidates: int
    n_fields: int
    n_cells: int

    @property
    def off_B(self) -> int:
        return 0

    @property
    def off_x(self) -> int:
        return self.n_blocks * self.n_candidates

    @property
    def off_y(self) -> int:
        return self.off_x + self.n_fields

    @property
    def off_U(self) -> int:
        return self.off_y + self.n_cells

    @property
    def off_t(self) -> int:
        return self.off_U + self.n_blocks

    @property
    def off_d(self) -> int:
        return self.off_t + self.n_blocks

    def B(self, x: np.ndarray) -> np.ndarray:
        """(n_blocks, K) assignment matrix from a solution vector."""
        return x[: self.off_x].reshape(self.n_blocks, self.n_candidates)

    def t(self, x: np.ndarray) -> np.ndarray:
        """(n_blocks,) block starts (s)."""
        return x[self.off_t:self.off_t + self.n_blocks]

    def d(self, x: np.ndarray) -> np.ndarray:
        """(n_blocks,) block durations (s)."""
        return x[self.off_d:self.off_d + self.n_blocks]

    def coverage_objective(self, x: np.ndarray) -> float:
        """The objective of a solution vector."""
        return float(self.milp.c @ x)


def build_block_model(candidates: Candidates, cells: Cells, n_fields: int, params: BlockParams) -> BlockModel:
    """Assemble the block-division MILP (equations B0-B11 of ``docs/design/milp.md``).

    Parameters
    ----------
    candidates : Candidates
        (field, window) pairs; ``field`` indexes the shortlist (0..n_fields-1).
    cells : Cells
        Coverage cells over the same shortlist.
    n_fields : int
        Shortlist size.
    params : BlockParams
        Timing, b_max, b_size, penalty, gaps.

    Returns
    -------
    BlockModel
    """
    nb, K, F, C = params.n_blocks, len(candidates), n_fields, cells.n_cells
    H = params.horizon_s
    b_eff = min(params.b_size, F) if F else params.b_size
    # variable layout (see BlockModel): B, x, y, U, t, d
    cols = Columns()
    B, x, y = cols.family("B", nb * K), cols.family("x", F), cols.family("y", C)
    U, t, d = cols.family("U", nb), cols.family("t", nb), cols.family("d", nb)
    n_cols = cols.n
    blk = np.repeat(np.arange(nb), K)          # block of each B column
    cand = np.tile(np.arange(K), nb)           # candidate of each B column
    ts, te = np.asarray(candidates.start, float), np.asarray(candidates.end, float)
    extra = np.asarray(params.extra, float)
    rows = RowBuilder()
    _block_rows(rows, candidates, cells, params, b_eff, (B, x, y, U, t, d))

    A, lo, hi = rows.matrix(n_cols)
    # (B0) objective: Σ w_c y_c - p Σ B[i, k]
    c = np.zeros(n_cols)
    c[B.columns] = -params.penalty
    c[y.columns] = cells.weight
    col_lo = np.zeros(n_cols)
    col_hi = np.ones(n_cols)
    col_hi[t.columns] = H
    col_hi[d.columns] = H
    if K:
        # block i cannot start before the least durations of blocks 0..i-1 have passed
        lb = earliest_block_starts(params, float(ts.min()), b_eff)
        fits = np.maximum(ts[cand], lb[blk]) + params.least_duration_s(b_eff) + extra[blk] <= te[cand] + 1e-9
        col_hi[B.columns] = fits.astype(float)
    integer = np.zeros(n_cols, bool)
    integer[B.columns] = True
    integer[U.columns] = True
    milp = MilpModel(c, A, lo, hi, col_lo, col_hi, integer, rows.blocks(), cols.families())
    return BlockModel(milp, nb, K, F, C)


def _block_rows(rows: RowBuilder, candidates: Candidates, cells: Cells, params: BlockParams, b_eff: int,
                families: tuple) -> None:
    """Append the block model's rows (B1-B11) on the columns of ``families`` = (B, x, y, U, t, d)."""
    B, x, y, U, t, d = families
    nb, K, F, C = params.n_blocks, len(candidates), x.size, cells.n_cells
    H, s = params.horizon_s, params.per_visit_s
    blk = np.repeat(np.arange(nb), K)          # block of each B column
    cand = np.tile(np.arange(K), nb)           # candidate of each B column
    ts, te = np.asarray(candidates.start, float), np.asarray(candidates.end, float)
    extra = np.asarray(params.extra, float)
    ik = np.arange(nb * K)                     # one row per (block, candidate)
    blocks, fields, cells_ = np.arange(nb), np.arange(F), np.arange(C)

    # (B8) each field at most once: x_j - Σ_{i, k of j} B[i, k] = 0
    rows.block("B8 each field at most once", F,
               [(fields, x[fields], 1.0), (candidates.field[cand], B.columns, -1.0)], 0.0, 0.0)
    # (B4) cell coverage: y_c - Σ_{j ∋ c} x_j <= 0
    cell_of = np.repeat(cells_, np.diff(cells.indptr))
    rows.block("B4 cell coverage", C, [(cells_, y[cells_], 1.0), (cell_of, x[cells.fields], -1.0)], -np.inf, 0.0)
    # (B2) a block with an observation is used: B[i, k] - U[i] <= 0
    rows.block("B2 a block with an observation is used", nb * K,
               [(ik, B.columns, 1.0), (ik, U[blk], -1.0)], -np.inf, 0.0)
    # (B1) least block size: Σ_k B[i, k] - b_size U[i] >= 0
    rows.block("B1 least block size", nb, [(blk, B.columns, 1.0), (blocks, U[blocks], -float(b_eff))], 0.0, np.inf)
    # (B3) unused blocks last: U[i] - U[i-1] <= 0
    if nb > 1:
        later = np.arange(nb - 1)
        rows.block("B3 unused blocks last", nb - 1, [(later, U[later + 1], 1.0), (later, U[later], -1.0)],
                   -np.inf, 0.0)
    # (B9) duration: d[i] - 2 s n_i - (t_filt + e_i) U_i >= 0 ;  d[i] - s n_i - (cadence + e_i) U_i >= 0
    rows.block("B9 duration of both passes and a filter change", nb,
               [(blocks, d[blocks], 1.0), (blk, B.columns, -2.0 * s),
                (blocks, U[blocks], -(params.filter_change_s + extra))], 0.0, np.inf)
    rows.block("B9 duration of one pass and the cadence", nb,
               [(blocks, d[blocks], 1.0), (blk, B.columns, -s), (blocks, U[blocks], -(params.cadence_s + extra))],
               0.0, np.inf)
    # (B6) start inside every member's window: t[i] - T_s[k] B[i, k] >= 0
    rows.block("B6 start inside every member's window", nb * K,
               [(ik, t[blk], 1.0), (ik, B.columns, -ts[cand])], 0.0, np.inf)
    # (B5) end inside every member's window: t[i] + d[i] + (H - T_e[k]) B[i, k] <= H
    rows.block("B5 end inside every member's window", nb * K,
               [(ik, t[blk], 1.0), (ik, d[blk], 1.0), (ik, B.columns, H - te[cand])], -np.inf, H)
    # (B7) after the previous block ends: t[i] - t[i-1] - d[i-1] - (t_filt + g_{i-1}) U_i >= 0
    if nb > 1:
        i = np.arange(1, nb)
        r = np.arange(nb - 1)
        rows.block("B7 after the previous block ends", nb - 1,
                   [(r, t[i], 1.0), (r, t[i - 1], -1.0), (r, d[i - 1], -1.0),
                    (r, U[i], -(params.filter_change_s + np.asarray(params.gaps, float)))], 0.0, np.inf)
    # (B10) Σ_i d[i] <= time during which some candidate is observable (blocks are disjoint
    # and each lies inside a window): a valid cut the big-M rows alone do not give
    if K:
        rows.block("B10 total duration within the observable time", 1,
                   [(np.zeros(nb, np.int64), d[blocks], 1.0)], -np.inf, _union_length(ts, te))
    # (B11) horizon: t[i] + d[i] <= H
    rows.block("B11 horizon", nb, [(blocks, t[blocks], 1.0), (blocks, d[blocks], 1.0)], -np.inf, H)


def _union_length(start: np.ndarray, end: np.ndarray) -> float:
    """Length (s) of the union of intervals [start, end]."""
    order = np.argsort(start)
    s, e = start[order], end[order]
    reach = np.maximum.accumulate(e)
    new = np.concatenate([[True], s[1:] > reach[:-1]])
    group = np.cumsum(new) - 1
    group_end = np.zeros(group[-1] + 1)
    np.maximum.at(group_end, group, e)
    return float(np.maximum(group_end - s[new], 0.0).sum())


@dataclass(frozen=True)
class DecodedBlock:
    """A used block of a MILP solution.

    Attributes
    ----------
    index : int
        Block number (time order).
    start_s : float
        Planned start t_i (s).
    duration_s : float
        Planned duration d_i (s).
    candidates : numpy.ndarray
        Candidate indices in the block.
    """

    index: int
    start_s: float
    duration_s: float
    candidates: np.ndarray


def decode_blocks(model: BlockModel, x: np.ndarray) -> list[DecodedBlock]:
    """Used blocks of a solution, in time order, non-empty only."""
    B = model.B(x) > 0.5
    t, d = model.t(x), model.d(x)
    out = []
    for i in np.argsort(t, kind="stable"):
        members = np.flatnonzero(B[i])
        if members.size:
            out.append(DecodedBlock(len(out), float(t[i]), float(d[i]), members))
    return out


def _field_cell_matrix(cells: Cells, n_fields: int) -> sp.csr_matrix:
    """(n_fields, C) incidence: field j contains cell c."""
    cell_of = np.repeat(np.arange(cells.n_cells), np.diff(cells.indptr))
    return sp.csr_matrix((np.ones(cell_of.size), (cells.fields, cell_of)), shape=(n_fields, cells.n_cells))


def heuristic_start(model: BlockModel, candidates: Candidates, cells: Cells, params: BlockParams) -> np.ndarray | None:
    """A feasible solution built block by block, to start the solver from.

    Blocks are made in time order: from the time the previous block ends,
    the earliest moment (that time or a later window opening) at which at
    least b_size fields can form a block; fields are added by marginal
    probability while every member's window still holds the longer block.

    Parameters
    ----------
    model : BlockModel
        The assembled model (for the variable layout and a feasibility check).
    candidates, cells, params
        As given to :func:`build_block_model`.

    Returns
    -------
    numpy.ndarray or None
        A solution vector satisfying every constraint, or None when the
        construction failed the check (the solver then starts cold).
    """
    nb, K, F = model.n_blocks, model.n_candidates, model.n_fields
    if K == 0:
        return None
    b_eff = min(params.b_size, F)
    H = params.horizon_s
    M = _field_cell_matrix(cells, F)
    weight = np.asarray(cells.weight, float)
    covered = np.zeros(cells.n_cells, bool)
    used = np.zeros(F, bool)
    x = np.zeros(model.milp.n_vars)
    B = np.zeros((nb, K))
    t_free = 0.0
    starts = np.unique(candidates.start)
    t_blk = np.zeros(nb)
    d_blk = np.zeros(nb)
    n_used = 0
    for i in range(nb):
        extra = float(params.extra[i])
        made = None
        for t0 in np.concatenate([[t_free], starts[starts > t_free]]):
            if t0 + params.least_duration_s(b_eff) + extra > H:
                break
            alive = ~used[candidates.field] & (candidates.start <= t0)
            alive &= candidates.end >= t0 + params.least_duration_s(b_eff) + extra
            if np.unique(candidates.field[alive]).size < b_eff:
                continue
            members: list[int] = []
            cov = covered.copy()
            taken = used.copy()
            net = 0.0
            while True:
                dur = params.least_duration_s(len(members) + 1) + extra
                end_ok = candidates.end >= t0 + dur
                if members and not end_ok[members].all():
                    break
                ok = alive & end_ok & ~taken[candidates.field]
                if not ok.any():
                    break
                gain_f = M @ (weight * ~cov)
                gain = np.where(ok, gain_f[candidates.field], -np.inf)
                k = int(np.argmax(gain))
                if gain[k] <= params.penalty and len(members) >= b_eff:
                    break
                members.append(k)
                net += gain[k] - params.penalty
                taken[candidates.field[k]] = True
                cov |= M[candidates.field[k]].toarray().ravel() > 0
            if len(members) >= b_eff and net > 0:
                made = (t0, members, cov, taken)
                break
        if made is None:
            break
        t0, members, covered, used = made
        B[i, members] = 1.0
        t_blk[i] = t0
        d_blk[i] = params.least_duration_s(len(members)) + extra
        n_used = i + 1
        gap = float(params.gaps[i]) if i < nb - 1 else 0.0
        t_free = t0 + d_blk[i] + params.filter_change_s + gap
    for i in range(n_used, nb):  # unused blocks sit where the last used one ends
        t_blk[i] = min(H, t_blk[i - 1] + d_blk[i - 1]) if i else 0.0
    x[: model.off_x] = B.ravel()
    xf = np.zeros(F)
    np.add.at(xf, candidates.field, B.sum(axis=0))
    x[model.off_x:model.off_y] = xf
    x[model.off_y:model.off_U] = np.minimum(1.0, M.T @ xf)
    x[model.off_U:model.off_t] = (np.arange(nb) < n_used).astype(float)
    x[model.off_t:model.off_d] = t_blk
    x[model.off_d:model.off_d + nb] = d_blk
    ax = model.milp.A @ x
    tol = 1e-6
    if (np.all(ax >= model.milp.row_lo - tol) and np.all(ax <= model.milp.row_hi + tol)
            and np.all(x >= model.milp.col_lo - tol) and np.all(x <= model.milp.col_hi + tol)):
        return x
    return None


def earliest_block_starts(params: BlockParams, first_open_s: float, b_eff: int) -> np.ndarray:
    """Lower bound (s) on each block's start: earlier blocks need their least duration."""
    step = params.least_duration_s(b_eff) + params.filter_change_s
    gaps = np.concatenate([[0.0], np.cumsum(np.asarray(params.gaps, float))]) if params.n_blocks > 1 else np.zeros(1)
    ext = np.concatenate([[0.0], np.cumsum(np.asarray(params.extra, float))[:-1]])
    return first_open_s + step * np.arange(params.n_blocks) + gaps[:params.n_blocks] + ext
