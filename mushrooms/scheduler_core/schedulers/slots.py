"""The fixed-grid slot-assignment MILP: grid, eligibility, model, decoding.

The observable time is cut once into back-to-back *blocks* of ``n``
position pairs (``docs/design/milp.md``, section "Slot-assignment MILP").
Position ``q`` of block ``j`` has fixed exposure starts (s since the
horizon start)

    t1 = T_j + q s                          (first filter)
    t2 = T_j + D_n + q s,   D_n = max(n s + t_filt, cadence)   (second filter)

with ``s = t_exp + t_slew`` (the slew estimate).  A block lasts
``L_n = D_n + n s + t_filt + margin``: both passes, the filter change back
to the first filter and a small margin for slews longer than the estimate.
A (field, slot) pair is *eligible* only when both of its exposures lie
inside a window of the field, so every constraint is a plain assignment
row: no big-M, no continuous times.

Variables: ``x_k`` binary for each eligible pair ``k = (field, slot)``;
``z_f`` in [0, 1] (field f is observed); ``y_c`` in [0, 1] (cell c is
covered).  (S0) Maximise ``Σ_c w_c y_c + Σ_k v_k x_k − p Σ_f z_f`` subject to

- (S1) ``Σ_{k ∋ slot} x_k <= 1``: one field per position;
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

from ..sky.cells import Cells, merge_cells
from ..config import PlanningConfig
from ..problem import PlanningProblem
from ..sky.windows import union_intervals
from .rows import Columns, Family, RowBuilder
from .solvers import MilpModel

__all__ = ["SlotGrid", "SlotInstance", "SlotModel", "block_length_s", "second_pass_delay_s",
           "observable_segments", "make_slot_grid", "eligible_pairs", "slot_instance", "build_slot_model",
           "slot_model_rows", "decode_slots", "start_vector"]

#: Phases of the grid: blocks laid out from each segment's start, or ending at its end.
PHASES = ("start", "end")


def second_pass_delay_s(n: int, config: PlanningConfig) -> float:
    """D_n (s): from a position's first-filter start to its second-filter start."""
    s = config.exposure_s + config.slew_estimate_s
    return max(n * s + config.filter_change_s, config.cadence_s)


def block_length_s(n: int, config: PlanningConfig) -> float:
    """L_n (s): a block of ``n`` positions from its first start to the next block's."""
    s = config.exposure_s + config.slew_estimate_s
    return second_pass_delay_s(n, config) + n * s + config.filter_change_s + config.slot_margin_s


def _active_s(n: int, config: PlanningConfig) -> float:
    """From a block's first start to the end of its last exposure (s)."""
    s = config.exposure_s + config.slew_estimate_s
    return second_pass_delay_s(n, config) + (n - 1) * s + config.exposure_s


@dataclass(frozen=True)
class SlotGrid:
    """Fixed exposure times of every position of every block.

    Attributes
    ----------
    n_positions : int
        n, positions of a full block.
    phase : str
        ``start`` or ``end`` (see :func:`make_slot_grid`).
    block_start : numpy.ndarray
        (J,) T_j (s), in time order.
    block_size : numpy.ndarray
        (J,) positions of block j (n, or fewer for a segment's partial block).
    slot_block, slot_position : numpy.ndarray
        (S,) block j and position q of each slot.
    t1, t2 : numpy.ndarray
        (S,) first- and second-filter exposure starts (s).
    """

    n_positions: int
    phase: str
    block_start: np.ndarray
    block_size: np.ndarray
    slot_block: np.ndarray
    slot_position: np.ndarray
    t1: np.ndarray
    t2: np.ndarray

    @property
    def n_slots(self) -> int:
        """Number of slots S."""
        return int(self.t1.size)

    @property
    def name(self) -> str:
        """Short label, e.g. ``n6/start``."""
        return f"n{self.n_positions}/{self.phase}"


def observable_segments(problem: PlanningProblem, rows: np.ndarray | None = None) -> list[tuple[float, float]]:
    """Disjoint time intervals (s) in which at least one of the fields is observable.

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray, optional
        Rows of ``problem.field_ids`` to consider (default all).

    Returns
    -------
    list of (start, end)
        In time order, clipped to the horizon.
    """
    w = problem.windows
    sel = np.ones(w.field_ids.size, bool) if rows is None else np.isin(w.field_ids, problem.field_ids[rows])
    starts, ends = union_intervals(np.clip(w.start[sel], 0.0, problem.horizon_s),
                                   np.clip(w.end[sel], 0.0, problem.horizon_s))
    return [(float(s), float(e)) for s, e in zip(starts, ends)]


def make_slot_grid(segments: list[tuple[float, float]], config: PlanningConfig, n: int,
                   phase: str = "start") -> SlotGrid:
    """Cut the observable segments into back-to-back blocks of ``n`` positions.

    Each segment holds as many full blocks as fit (the last exposure of a
    block ends inside the segment) and, in the time left, one partial
    block of the most positions that still fit.  Phase ``start`` lays the
    full blocks out from the segment's start, the partial block last;
    phase ``end`` puts the partial block first and ends the last block at
    the segment's end.

    Parameters
    ----------
    segments : list of (start, end)
        Observable intervals (s), e.g. from :func:`observable_segments`.
    config : PlanningConfig
        Exposure, slew estimate, filter change, cadence and ``slot_margin_s``.
    n : int
        Positions per full block (>= 1).
    phase : str
        ``start`` or ``end``.

    Returns
    -------
    SlotGrid
    """
    if n < 1:
        raise ValueError(f"a block needs at least one position, got n={n}")
    if phase not in PHASES:
        raise ValueError(f"phase must be one of {PHASES}, got {phase!r}")
    s = config.exposure_s + config.slew_estimate_s
    starts: list[float] = []
    sizes: list[int] = []
    for a, b in segments:
        length = b - a
        if length < _active_s(1, config):
            continue
        L = block_length_s(n, config)
        n_full = int(np.floor((length - _active_s(n, config)) / L + 1e-9)) + 1 if length >= _active_s(n, config) else 0
        left = length - n_full * L  # time after the last full block's full length
        partial = 0
        for m in range(n - 1, 0, -1):
            if _active_s(m, config) <= left + 1e-9:
                partial = m
                break
        layout = [n] * n_full + ([partial] if partial else [])
        if phase == "end":
            layout = ([partial] if partial else []) + [n] * n_full
        t = a
        block_t = []
        for m in layout:
            block_t.append(t)
            t += block_length_s(m, config)
        if phase == "end" and layout:
            shift = b - (block_t[-1] + _active_s(layout[-1], config))
            block_t = [x + max(shift, 0.0) for x in block_t]
        starts += block_t
        sizes += layout
    T = np.asarray(starts, float)
    size = np.asarray(sizes, np.int64)
    slot_block = np.repeat(np.arange(T.size), size)
    first = np.concatenate([[0], np.cumsum(size)[:-1]]) if size.size else np.zeros(0, np.int64)
    slot_position = np.arange(int(size.sum())) - np.repeat(first, size)
    delay = np.array([second_pass_delay_s(int(m), config) for m in size]) if size.size else np.zeros(0)
    t1 = T[slot_block] + slot_position * s
    t2 = t1 + delay[slot_block]
    return SlotGrid(n, phase, T, size, slot_block, slot_position.astype(np.int64), t1, t2)


def eligible_pairs(problem: PlanningProblem, rows: np.ndarray, grid: SlotGrid, exposure_s: float | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(field, slot) pairs whose two exposures each lie inside a window of the field.

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray
        Rows of ``problem.field_ids`` taking part (the model's fields are
        ``0..len(rows)-1`` in this order).
    grid : SlotGrid
    exposure_s : float, optional
        Length (s) of each of the pair's two exposures; default
        ``config.exposure_s``.

    Returns
    -------
    field, slot : numpy.ndarray
        (K,) model field index and slot index of each eligible pair.
    window1, window2 : numpy.ndarray
        (K,) index into ``problem.windows`` of the window holding the first
        and the second exposure.
    """
    w = problem.windows
    e = problem.config.exposure_s if exposure_s is None else float(exposure_s)
    ids = problem.field_ids[np.asarray(rows, np.int64)]
    lookup = {int(f): i for i, f in enumerate(ids)}
    w_field = np.array([lookup.get(int(f), -1) for f in w.field_ids], np.int64)
    wsel = np.flatnonzero(w_field >= 0)
    H = problem.horizon_s
    ws, we = w.start[wsel][:, None], np.minimum(w.end[wsel], H)[:, None]
    in1 = (ws <= grid.t1[None, :]) & (grid.t1[None, :] + e <= we)     # (W, S)
    in2 = (ws <= grid.t2[None, :]) & (grid.t2[None, :] + e <= we)
    F = len(ids)
    # per field: the first window holding each exposure (-1: none)
    win1 = np.full((F, grid.n_slots), -1, np.int64)
    win2 = np.full((F, grid.n_slots), -1, np.int64)
    for arr, inside in ((win1, in1), (win2, in2)):
        wi, si = np.nonzero(inside)
        # later windows first, so the earliest one is written last and wins
        order = np.argsort(-wi, kind="stable")
        arr[w_field[wsel[wi[order]]], si[order]] = wsel[wi[order]]
    f, slot = np.nonzero((win1 >= 0) & (win2 >= 0))
    return f.astype(np.int64), slot.astype(np.int64), win1[f, slot], win2[f, slot]


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
                            pick(self.pair_span))

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
    from .block_schedule import shortlist_footprints

    rows = np.asarray(rows, np.int64)
    if cells is None:
        weight = problem.prob if pixel_weight is None else np.asarray(pixel_weight, float)
        cells = merge_cells(shortlist_footprints(problem.footprints, rows), weight)
    f, slot, w1, w2 = eligible_pairs(problem, rows, grid)
    return SlotInstance(rows, grid, cells, f, slot, w1, w2)


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


def slot_model_rows(rows: RowBuilder, instance: SlotInstance, x: Family, z: Family, y: Family) -> None:
    """Append the slot model's rows (S1 or X7, S2, S3) on the columns of pairs ``x``, fields ``z``, cells ``y``."""
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
