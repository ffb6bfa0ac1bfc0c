"""The fixed-grid slot-assignment MILP: eligibility, model, decoding (the grid: :mod:`.grid`).

The observable time is cut once into back-to-back *blocks* of ``n``
positions (``docs/design/milp.md``, section "Slot-assignment MILP").  A
block is ``k`` filter passes over its positions, one per filter of the
sequence ``S = (s_1, ..., s_k)`` (``[scheduler] filters``, F0; the pair
``k = 2`` by default).  Position ``q`` of block ``j`` has fixed exposure
starts (s since the horizon start)

    t_p = T_j + (p - 1) D_n + q s,   D_n = max(n s + t_filt, cadence),   p = 1..k   (G1)

with ``s = t_exp + t_slew`` (the slew estimate), so consecutive visits of
a position are ``D_n >= cadence`` apart.  A block lasts
``L_n = (k - 1) D_n + n s + δ t_filt + margin`` (G2): every pass, the
filter change back to ``s_1`` when ``s_k != s_1`` (``δ = 1``; a g-r-g block
ends in the next block's filter) and a small margin for slews longer than
the estimate.  A (field, slot) pair is *eligible* only when each of its
``k`` exposures lies inside a window of the field and, for ``k > 2``, the
last starts at most the pair separation ``M`` after the first (G3), so
every constraint is a plain assignment row: no big-M, no continuous times.
A chosen slot is the field's whole sequence: its first two visits cover it
(F1), the later ones take their passes' time.

Variables: ``x_k`` binary for each eligible pair ``k = (field, slot)``;
``z_f`` in [0, 1] (field f is observed); ``y_c`` in [0, 1] (cell c is
covered).  (S0) Maximise ``Σ_c w_c y_c + Σ_k v_k x_k − p Σ_f z_f`` subject to

- (S1) ``Σ_{k ∋ slot} x_k <= 1``: one field per position (all passes);
- (S2) ``z_f − Σ_{k ∋ f} x_k = 0``, ``z_f <= 1``: each field at most once;
- (S3) ``y_c − Σ_{f ∋ c} z_f <= 0``: a cell counts when a field holding it
  is observed.

The cell weights ``w`` are the probability by default; a caller may pass
any per-pixel weight (e.g. a detection probability), and per-pair weights
``v`` (zero by default), through :func:`slot_instance` and
:func:`build_slot_model`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...sky.cells import Cells, merge_cells
from ...problem import PlanningProblem
from ..milp.rows import Columns, Family, RowBuilder
from .grid import SlotGrid, block_length_s, make_slot_grid, n_passes, observable_segments, second_pass_delay_s
from ..milp.solvers import MilpModel

__all__ = ["SlotGrid", "SlotInstance", "SlotModel", "block_length_s", "second_pass_delay_s", "n_passes",
           "observable_segments", "make_slot_grid", "eligible_pairs", "eligible_visits", "slot_instance", "build_slot_model",
           "slot_model_rows", "decode_slots", "start_vector"]


def eligible_pairs(problem: PlanningProblem, rows: np.ndarray, grid: SlotGrid, exposure_s: float | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(field, slot) pairs whose exposures each lie inside a window of the field.

    :func:`eligible_visits` with the windows of the first two passes.

    Returns
    -------
    field, slot : numpy.ndarray
        (K,) model field index and slot index of each eligible pair.
    window1, window2 : numpy.ndarray
        (K,) index into ``problem.windows`` of the window holding the first
        and the second exposure.
    """
    f, slot, win = eligible_visits(problem, rows, grid, exposure_s)
    return f, slot, win[:, 0], win[:, 1]


def eligible_visits(problem: PlanningProblem, rows: np.ndarray, grid: SlotGrid, exposure_s: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(field, slot) pairs whose ``k`` exposures each lie inside a window of the field (G3).

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray
        Rows of ``problem.field_ids`` taking part (the model's fields are
        ``0..len(rows)-1`` in this order).
    grid : SlotGrid
    exposure_s : float, optional
        Length (s) of each exposure; default ``config.exposure_s``.

    Returns
    -------
    field, slot : numpy.ndarray
        (K,) model field index and slot index of each eligible pair.
    windows : numpy.ndarray
        (K, k) index into ``problem.windows`` of the window holding each
        pass's exposure (the earliest such window).
    """
    w = problem.windows
    e = problem.config.exposure_s if exposure_s is None else float(exposure_s)
    ids = problem.field_ids[np.asarray(rows, np.int64)]
    lookup = {int(f): i for i, f in enumerate(ids)}
    w_field = np.array([lookup.get(int(f), -1) for f in w.field_ids], np.int64)
    wsel = np.flatnonzero(w_field >= 0)
    H = problem.horizon_s
    ws, we = w.start[wsel][:, None], np.minimum(w.end[wsel], H)[:, None]
    F = len(ids)
    wins = []
    for t in grid.pass_starts:
        inside = (ws <= t[None, :]) & (t[None, :] + e <= we)  # (W, S)
        # per field: the first window holding the exposure (-1: none)
        win = np.full((F, grid.n_slots), -1, np.int64)
        wi, si = np.nonzero(inside)
        # later windows first, so the earliest one is written last and wins
        order = np.argsort(-wi, kind="stable")
        win[w_field[wsel[wi[order]]], si[order]] = wsel[wi[order]]
        wins.append(win)
    ok = np.logical_and.reduce([win >= 0 for win in wins])
    if len(wins) > 2:  # (G3) a sequence's last visit within the pair separation of its first
        ok &= (grid.pass_starts[-1] - grid.t1 <= problem.config.pair_separation_s)[None, :]
    f, slot = np.nonzero(ok)
    windows = np.stack([win[f, slot] for win in wins], axis=1).reshape(f.size, len(wins))
    return f.astype(np.int64), slot.astype(np.int64), windows


@dataclass(frozen=True)
class SlotInstance:
    """One grid's data for the model: fields, cells, eligible pairs.

    Attributes
    ----------
    rows : numpy.ndarray
        (F,) rows of ``problem.field_ids`` (model field f = ``rows[f]``).
    grid : SlotGrid
    cells : Cells
        Cells over those fields, weighted by the objective's pixel weight.
    pair_field, pair_slot : numpy.ndarray
        (K,) eligible pairs.
    pair_window1, pair_window2 : numpy.ndarray
        (K,) windows (indices into ``problem.windows``) holding each exposure.
    pair_exposure : numpy.ndarray or None
        (K,) exposure (s) of each pair's two visits; None: every pair
        ``config.exposure_s`` (the grid's own).
    pair_span : numpy.ndarray or None
        (K,) consecutive positions, from ``pair_slot`` on, each pair
        occupies in both passes (X7); None: one each.
    pair_window_later : numpy.ndarray or None
        (K, k - 2) windows holding the exposures of the passes after the
        second (G1); None for the pair.
    open_shutter_cap_s : float or None
        (S4) most open-shutter time (s) of the chosen pairs' exposures
        (``[scheduler] max_open_shutter_s``); None: no cap, no S4 row.
    exposure_s : float
        Exposure (s) of a pair without ``pair_exposure`` (the grid's own),
        counted by S4.
    """

    rows: np.ndarray
    grid: SlotGrid
    cells: Cells
    pair_field: np.ndarray
    pair_slot: np.ndarray
    pair_window1: np.ndarray
    pair_window2: np.ndarray
    pair_exposure: np.ndarray | None = None
    pair_span: np.ndarray | None = None
    pair_window_later: np.ndarray | None = None
    open_shutter_cap_s: float | None = None
    exposure_s: float = 0.0

    def windows(self) -> np.ndarray:
        """(K, k) the window (index into ``problem.windows``) holding each pass's exposure of every pair."""
        later = np.zeros((self.n_pairs, 0), np.int64) if self.pair_window_later is None else self.pair_window_later
        return np.column_stack([self.pair_window1, self.pair_window2, later]).astype(np.int64)

    def exposures(self, default_s: float) -> np.ndarray:
        """(K,) exposure (s) of every pair (``default_s`` without a menu)."""
        if self.pair_exposure is None:
            return np.full(self.n_pairs, float(default_s))
        return np.asarray(self.pair_exposure, float)

    def subset(self, keep: np.ndarray) -> "SlotInstance":
        """The same instance with only the pairs ``keep`` (indices or a mask)."""
        pick = (lambda a: None if a is None else np.asarray(a)[keep])
        return SlotInstance(self.rows, self.grid, self.cells, self.pair_field[keep], self.pair_slot[keep],
                            self.pair_window1[keep], self.pair_window2[keep], pick(self.pair_exposure),
                            pick(self.pair_span), pick(self.pair_window_later), self.open_shutter_cap_s,
                            self.exposure_s)

    @property
    def n_fields(self) -> int:
        """F."""
        return int(self.rows.size)

    @property
    def n_pairs(self) -> int:
        """K, the binaries of the model."""
        return int(self.pair_field.size)


def slot_instance(problem: PlanningProblem, rows: np.ndarray, grid: SlotGrid,
                  pixel_weight: np.ndarray | None = None, cells: Cells | None = None) -> SlotInstance:
    """Eligible pairs and weighted cells of one grid.

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray
        Rows of ``problem.field_ids`` that may be scheduled.
    grid : SlotGrid
    pixel_weight : numpy.ndarray, optional
        Objective weight per pixel (NESTED, the problem's nside); default
        the sky map probability.  Pixels of weight 0 take no part.
    cells : Cells, optional
        Cells already merged for these rows and weights (shared by the
        grids of a portfolio).

    Returns
    -------
    SlotInstance
    """
    from ..blocks.schedule import shortlist_footprints

    rows = np.asarray(rows, np.int64)
    if cells is None:
        weight = problem.prob if pixel_weight is None else np.asarray(pixel_weight, float)
        cells = merge_cells(shortlist_footprints(problem.footprints, rows), weight)
    f, slot, win = eligible_visits(problem, rows, grid)
    later = win[:, 2:] if win.shape[1] > 2 else None
    cfg = problem.config
    return SlotInstance(rows, grid, cells, f, slot, win[:, 0], win[:, 1], pair_window_later=later,
                        open_shutter_cap_s=cfg.max_open_shutter_s, exposure_s=cfg.exposure_s)


@dataclass(frozen=True)
class SlotModel:
    """The assembled slot MILP; variables ``[x (K) | z (F) | y (C)]``.

    Attributes
    ----------
    milp : MilpModel
    instance : SlotInstance
    """

    milp: MilpModel
    instance: SlotInstance

    @property
    def off_z(self) -> int:
        """Offset of the field variables z."""
        return self.instance.n_pairs

    @property
    def off_y(self) -> int:
        """Offset of the cell variables y."""
        return self.off_z + self.instance.n_fields


def build_slot_model(instance: SlotInstance, penalty: float = 0.0,
                     pair_weight: np.ndarray | None = None) -> SlotModel:
    """Assemble the slot-assignment MILP (equations S0–S3 of ``docs/design/milp.md``).

    Parameters
    ----------
    instance : SlotInstance
    penalty : float
        p, subtracted per observed field.
    pair_weight : numpy.ndarray, optional
        (K,) v_k added per chosen pair (e.g. a preference for early slots);
        default 0.

    Returns
    -------
    SlotModel
    """
    K, F, C = instance.n_pairs, instance.n_fields, instance.cells.n_cells
    cols = Columns()
    x, z, y = cols.family("x", K), cols.family("z", F), cols.family("y", C)
    rows = RowBuilder()
    slot_model_rows(rows, instance, x, z, y)
    A, lo, hi = rows.matrix(cols.n)
    # (S0) objective: Σ w_c y_c + Σ v_k x_k - p Σ z_f
    obj = np.zeros(cols.n)
    if pair_weight is not None:
        obj[x.columns] = np.asarray(pair_weight, float)
    obj[z.columns] = -float(penalty)
    obj[y.columns] = instance.cells.weight
    integer = np.zeros(cols.n, bool)
    integer[x.columns] = True
    milp = MilpModel(obj, A, lo, hi, np.zeros(cols.n), np.ones(cols.n), integer, rows.blocks(), cols.families())
    return SlotModel(milp, instance)


def slot_model_rows(rows: RowBuilder, instance: SlotInstance, x: Family, z: Family, y: Family | None,
                    cover: bool = True) -> None:
    """Append the slot model's rows (S1 or X7, S2, S3) on the columns of pairs ``x``, fields ``z``, cells ``y``.

    ``cover = False`` leaves S3 out (``y`` unused): a joint model of several
    telescopes couples their fields through its own cell rows
    (``docs/design/telescopes.md``, J2).
    """
    K, F, C = instance.n_pairs, instance.n_fields, instance.cells.n_cells
    S = instance.grid.n_slots
    k = np.arange(K)
    if instance.pair_span is None:
        # (S1) one field per position: Σ_{k ∋ slot} x_k <= 1
        rows.block("S1 one field per position", S, [(instance.pair_slot, x[k], 1.0)], -np.inf, 1.0)
    else:
        # (X7) one field per position, a pair holding its span: Σ_{k : s_k <= slot < s_k + n_k} x_k <= 1
        span = np.asarray(instance.pair_span, np.int64)
        kk = np.repeat(k, span)
        first = np.concatenate([[0], np.cumsum(span)[:-1]])
        held = instance.pair_slot[kk] + np.arange(kk.size) - np.repeat(first, span)
        rows.block("X7 one field per position over its span", S, [(held, x[kk], 1.0)], -np.inf, 1.0)
    # (S2) each field at most once: z_f - Σ_{k ∋ f} x_k = 0  (z_f <= 1 is its bound)
    rows.block("S2 each field at most once", F,
               [(np.arange(F), z[np.arange(F)], 1.0), (instance.pair_field, x[k], -1.0)], 0.0, 0.0)
    if instance.open_shutter_cap_s is not None:
        # (S4) open-shutter cap: Σ_k k_p e_k x_k <= T_open (every pass of a chosen pair exposes e_k)
        seconds = len(instance.grid.pass_starts) * instance.exposures(instance.exposure_s)
        rows.block("S4 open-shutter cap", 1, [(np.zeros(K, np.int64), x[k], seconds)], -np.inf,
                   float(instance.open_shutter_cap_s))
    if not cover:
        return
    # (S3) cell coverage: y_c - Σ_{f ∋ c} z_f <= 0
    cells = instance.cells
    cell_of = np.repeat(np.arange(C), np.diff(cells.indptr))
    rows.block("S3 cell coverage", C, [(np.arange(C), y[np.arange(C)], 1.0), (cell_of, z[cells.fields], -1.0)],
               -np.inf, 0.0)


def decode_slots(model: SlotModel, x: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """Chosen pairs grouped by block: ``[(block j, pair indices in position order)]``, time order."""
    inst = model.instance
    chosen = np.flatnonzero(x[:inst.n_pairs] > 0.5)
    blk = inst.grid.slot_block[inst.pair_slot[chosen]]
    pos = inst.grid.slot_position[inst.pair_slot[chosen]]
    order = np.lexsort((pos, blk))
    chosen, blk = chosen[order], blk[order]
    return [(int(j), chosen[blk == j]) for j in np.unique(blk)]


def start_vector(model: SlotModel, pairs: np.ndarray) -> np.ndarray:
    """A full solution vector choosing the given pairs (x, z and the best y).

    Parameters
    ----------
    model : SlotModel
    pairs : numpy.ndarray
        Pair indices; at most one per slot and per field (not checked here).
    """
    inst = model.instance
    x = np.zeros(model.milp.n_vars)
    x[np.asarray(pairs, np.int64)] = 1.0
    z = np.zeros(inst.n_fields)
    z[inst.pair_field[np.asarray(pairs, np.int64)]] = 1.0
    x[model.off_z:model.off_y] = z
    cells = inst.cells
    cell_of = np.repeat(np.arange(cells.n_cells), np.diff(cells.indptr))
    covered = np.zeros(cells.n_cells)
    np.maximum.at(covered, cell_of, z[cells.fields])
    x[model.off_y:] = covered
    return x
