"""The continuous-time model of the full planning rules (equations C0–C6 of ``docs/design/milp.md``).

Every field is observed in both filters or not at all, each exposure at a
continuous start time inside one of the field's windows, the two filters
the cadence apart in either order, and any two exposures at least the
exposure plus their true overhead apart (``max(slew, readout, filter
change)``, the checker's rule), in one of the two orders: m4opt-style
pairwise disjunctions with big-M taken from the windows (never more than
the night).  Because an exposure (300 s) outlasts any overhead, "every
pair apart" is the same as "every consecutive pair apart", so an integral
solution is exactly a rule-abiding plan and every rule-abiding plan is one.
Interval capacity cuts (C6) make the LP relaxation count the competition
for time.

Two users: the exact optimum of reduced instances
(``mushrooms.evaluation.exact``, benchmark only) and the large-neighbourhood
re-solves of the hybrid (:mod:`.lns`, equations H1–H5), which solve it on a
time slice of the night with the rest of the plan fixed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...sequences import require_pair
from ...plan.document import Observation
from ...problem import PlanningProblem
from ...sky.cells import Cells, merge_cells
from ..blocks.schedule import shortlist_footprints
from ...telescope.slew import slew_time
from ..milp.rows import Columns, Family, RowBuilder, at_least_when
from ..milp.solvers import MilpModel

__all__ = ["ExactData", "ExactModel", "exact_data", "build_exact_model", "start_from_plan", "decode_exact",
           "INTEGRAL_TOL"]

#: Integral values closer than this to 0 or 1 are read as 0 or 1.
INTEGRAL_TOL = 1e-3


@dataclass(frozen=True)
class ExactData:
    """The problem's fields, exposures, windows and overheads as the exact model reads them.

    Exposure ``e = 2 f + φ`` is field ``f`` (row ``rows[f]``) in filter ``φ``
    (0: ``filters[0]``, 1: ``filters[1]``).

    Attributes
    ----------
    rows : numpy.ndarray
        (F,) rows of ``problem.field_ids``.
    windows : list of list of (float, float)
        Per field, its windows (s) clipped to the horizon that hold one exposure.
    lo, hi : numpy.ndarray
        (F,) earliest and latest exposure start (s) of each field.
    pairable : numpy.ndarray
        (F,) True when ``hi - lo >= cadence``: the field can hold its pair.
    overhead : numpy.ndarray
        (2F, 2F) least time (s) from the end of exposure e to the start of e'
        when e' follows e: ``max(slew, readout, filter change if the filter changes)``.
    cells : Cells
        Coverage cells of the fields (weights: the sky map's probability).
    """

    rows: np.ndarray
    windows: list[list[tuple[float, float]]]
    lo: np.ndarray
    hi: np.ndarray
    pairable: np.ndarray
    overhead: np.ndarray
    cells: Cells

    @property
    def n_fields(self) -> int:
        """F."""
        return int(self.rows.size)


def exact_data(problem: PlanningProblem, rows: np.ndarray | None = None) -> ExactData:
    """Windows, overheads and cells of the fields of ``problem`` (all rows by default)."""
    cfg = problem.config
    H, exp = problem.horizon_s, cfg.exposure_s
    rows = np.arange(len(problem.field_ids)) if rows is None else np.asarray(rows, np.int64)
    F = rows.size
    windows: list[list[tuple[float, float]]] = []
    lo, hi = np.zeros(F), np.zeros(F)
    for f, row in enumerate(rows):
        ws = [(max(a, 0.0), min(b, H)) for a, b in problem.windows.for_field(int(problem.field_ids[row]))]
        ws = [(a, b) for a, b in ws if b - a >= exp]
        windows.append(ws)
        lo[f] = min((a for a, _ in ws), default=0.0)
        hi[f] = max((b - exp for _, b in ws), default=-math.inf)
    pairable = hi - lo >= cfg.cadence_s
    hi = np.where(np.isfinite(hi), hi, lo)
    ra, dec = problem.ra[rows], problem.dec[rows]
    slew = slew_time(ra[:, None], dec[:, None], ra[None, :], dec[None, :], cfg.slew)
    slew_e = np.repeat(np.repeat(slew, 2, axis=0), 2, axis=1)
    phi = np.tile([0, 1], F)
    change = np.where(phi[:, None] != phi[None, :], cfg.filter_change_s, 0.0)
    overhead = np.maximum(np.maximum(slew_e, cfg.slew.readout_s), change)
    cells = merge_cells(shortlist_footprints(problem.footprints, rows), problem.prob)
    return ExactData(rows, windows, lo, hi, pairable, overhead, cells)


@dataclass(frozen=True)
class ExactModel:
    """The assembled exact MILP and where each variable family sits.

    Variables ``[x (F) | d (F) | t (2F) | u (U) | o (P) | y (C)]``: field
    observed, filter order (1: ``filters[0]`` first), exposure starts (s),
    window choice of the exposures of fields with several windows, pair
    order (1: the lower exposure index first), cell covered.

    Attributes
    ----------
    milp : MilpModel
    data : ExactData
    u_exposure, u_window : numpy.ndarray
        (U,) exposure and window (index into ``data.windows[f]``) of each u.
    o_pair : numpy.ndarray
        (P, 2) the exposures (e < e') each o orders.
    n_cuts : int
        Interval capacity rows (C6).
    """

    milp: MilpModel
    data: ExactData
    u_exposure: np.ndarray
    u_window: np.ndarray
    o_pair: np.ndarray
    n_cuts: int

    @property
    def off_d(self) -> int:
        return self.data.n_fields

    @property
    def off_t(self) -> int:
        return 2 * self.data.n_fields

    @property
    def off_u(self) -> int:
        return 4 * self.data.n_fields

    @property
    def off_o(self) -> int:
        return self.off_u + int(self.u_exposure.size)

    @property
    def off_y(self) -> int:
        return self.off_o + int(self.o_pair.shape[0])


def build_exact_model(problem: PlanningProblem, data: ExactData | None = None) -> ExactModel:
    """Assemble the exact continuous-time MILP (equations C0–C6 of ``docs/design/milp.md``).

    Parameters
    ----------
    problem : PlanningProblem
        Its config gives exposure, cadence, readout and filter change (s).
    data : ExactData, optional
        Default :func:`exact_data` of every field of ``problem``.

    Returns
    -------
    ExactModel
    """
    require_pair(problem.config.filters, "exact continuous-time MILP")
    data = exact_data(problem) if data is None else data
    cfg = problem.config
    exp, cad, r = cfg.exposure_s, cfg.cadence_s, cfg.slew.readout_s
    F, C = data.n_fields, data.cells.n_cells
    lo, hi, oh = data.lo, data.hi, data.overhead
    lo_e, hi_e, f_of = np.repeat(lo, 2), np.repeat(hi, 2), np.repeat(np.arange(F), 2)

    multi = [f for f in range(F) if data.pairable[f] and len(data.windows[f]) > 1]
    u_exposure = np.array([2 * f + p for f in multi for p in (0, 1) for _ in data.windows[f]], np.int64)
    u_window = np.array([w for f in multi for p in (0, 1) for w in range(len(data.windows[f]))], np.int64)
    ok = np.flatnonzero(data.pairable)
    o_pair, forced, apart = _exposure_orders(ok, lo_e, hi_e, oh, exp)
    P, U = o_pair.shape[0], u_exposure.size
    cols = Columns()
    x, d, t = cols.family("x", F), cols.family("d", F), cols.family("t", 2 * F)  # t[2f + p]: filter p of f
    u, o, y = cols.family("u", U), cols.family("o", P), cols.family("y", C)
    n = cols.n
    rows = RowBuilder()

    # (C1) window choice: an observed field's exposure lies in one of its windows, Σ_w u_{e,w} = x_f
    for e in np.unique(u_exposure):
        k = np.flatnonzero(u_exposure == e)
        rows.row("C1 window choice", [*u[k], x[f_of[e]]], [*np.ones(k.size), -1.0], 0.0, 0.0)

    # (C2) inside the window chosen: a_w - (a_w - lo)(1 - u) <= t_e <= b_w - exp + (hi - b_w + exp)(1 - u)
    for k, (e, w) in enumerate(zip(u_exposure, u_window)):
        a, b = data.windows[f_of[e]][w]
        rows.row("C2 inside the window chosen", [t[e], u[k]], [1.0, -(a - lo_e[e])], lo_e[e], math.inf)
        rows.row("C2 inside the window chosen", [t[e], u[k]], [1.0, hi_e[e] - (b - exp)], -math.inf, hi_e[e])
    # (single-window fields: the bounds lo <= t_e <= hi below are that window)

    # (C3) cadence, either filter first: d_f = 1 -> t_{f,1} >= t_{f,0} + c; d_f = 0 -> t_{f,0} >= t_{f,1} + c
    for f in ok:
        M = cad + hi[f] - lo[f]
        first, second = t[2 * f], t[2 * f + 1]
        at_least_when(rows, "C3 cadence", [second, first], [1.0, -1.0], cad, [(d[f], 1), (x[f], 1)], M)
        at_least_when(rows, "C3 cadence", [first, second], [1.0, -1.0], cad, [(d[f], 0), (x[f], 1)], M)
        rows.row("C3 cadence", [d[f], x[f]], [1.0, -1.0], -math.inf, 0.0)

    # (C4) one exposure at a time: t_e' >= t_e + exp + oh(e, e') or t_e >= t_e' + exp + oh(e', e)
    for k, (e, e2) in enumerate(o_pair):
        both = [(x[f_of[e]], 1), (x[f_of[e2]], 1)]
        for first, second, o_first in ((e, e2, 1), (e2, e, 0)):  # o_k = 1 puts e first, o_k = 0 e2
            p = exp + oh[first, second]
            M = p + hi_e[first] - lo_e[second]
            at_least_when(rows, "C4 one exposure at a time", [t[second], t[first]], [1.0, -1.0], p,
                          [(o[k], o_first), *both], M)
    for first, second in forced:  # only "first before second" fits the windows
        p = exp + oh[first, second]
        M = p + hi_e[first] - lo_e[second]
        at_least_when(rows, "C4 one exposure at a time", [t[second], t[first]], [1.0, -1.0], p,
                      [(x[f_of[first]], 1), (x[f_of[second]], 1)], M)
    for f, g in sorted(set(apart)):  # neither order fits: not both
        rows.row("C4 one exposure at a time", [x[f], x[g]], [1.0, 1.0], -math.inf, 1.0)

    # (C5) cell coverage: y_l <= Σ_{f ∋ l} x_f
    cells = data.cells
    for c in range(C):
        members = cells.fields[cells.indptr[c]:cells.indptr[c + 1]]
        rows.row("C5 cell coverage", [y[c], *x[members]], [1.0, *(-np.ones(members.size))], -math.inf, 0.0)

    # (C6) interval capacity: the exposures the windows and the cadence hold inside [A, B] need (exp + r) each
    n_cuts = _capacity_cuts(rows, data, exp, cad, r, cfg.filter_change_s, x)

    # (C0) objective: maximise Σ_l w_l y_l
    c_obj = np.zeros(n)
    c_obj[y.columns] = cells.weight
    col_lo, col_hi = np.zeros(n), np.ones(n)
    col_hi[x.columns] = data.pairable.astype(float)
    col_lo[t.columns], col_hi[t.columns] = lo_e, hi_e
    integer = np.zeros(n, bool)
    integer[x.columns] = integer[d.columns] = True
    integer[u.columns] = integer[o.columns] = True
    A, row_lo, row_hi = rows.matrix(n)
    milp = MilpModel(c_obj, A, row_lo, row_hi, col_lo, col_hi, integer, rows.blocks(), cols.families())
    return ExactModel(milp, data, u_exposure, u_window, o_pair, n_cuts)


def _exposure_orders(ok: np.ndarray, lo_e: np.ndarray, hi_e: np.ndarray, oh: np.ndarray,
                     exp: float) -> tuple[np.ndarray, list, list]:
    """Which order each two exposures of different fields may take (for C4).

    Returns
    -------
    o_pair : numpy.ndarray
        (P, 2) exposure pairs either order fits: each gets an order binary.
    forced : list of (e, e')
        Pairs only "e before e'" fits.
    apart : list of (f, g)
        Field pairs that cannot both be observed.
    """
    pairs, forced, apart = [], [], []
    for i, f in enumerate(ok):
        for g in ok[i + 1:]:
            for e in (2 * f, 2 * f + 1):
                for e2 in (2 * g, 2 * g + 1):
                    ab = lo_e[e] + exp + oh[e, e2] <= hi_e[e2]
                    ba = lo_e[e2] + exp + oh[e2, e] <= hi_e[e]
                    if ab and ba:
                        pairs.append((e, e2))
                    elif ab:
                        forced.append((e, e2))
                    elif ba:
                        forced.append((e2, e))
                    else:
                        apart.append((f, g))
    return np.array(pairs, np.int64).reshape(-1, 2), forced, apart


def _capacity_cuts(rows: RowBuilder, data: ExactData, exp: float, cad: float, r: float, fc: float,
                   x: Family) -> int:
    """(C6) rows ``Σ_f k_f(A, B) (exp + r) x_f <= B - A + r`` that are not implied.

    A field observable in ``[lo, hi + exp]`` has its earlier exposure inside
    ``[lo, hi + exp - c]`` and its later one inside ``[lo + c, hi + exp]``
    (the cadence); ``k_f(A, B)`` counts those of the two intervals lying in
    ``[A, B]``.  ``A`` runs over the intervals' openings, ``B`` over their
    ends.  When every field counted has both exposures inside, the
    exposures change filter at least once, so the right-hand side is
    ``B - A + 2 r - max(t_filt, r)``.
    """
    ok = np.flatnonzero(data.pairable)
    if ok.size == 0:
        return 0
    lo, end = data.lo[ok], data.hi[ok] + exp
    early = np.stack([lo, end - cad], axis=1)  # the earlier exposure's interval
    late = np.stack([lo + cad, end], axis=1)  # the later one's
    n_cuts = 0
    seen: set[tuple[int, ...]] = set()
    for A in np.unique(np.concatenate([early[:, 0], late[:, 0]])):
        for B in np.unique(np.concatenate([early[:, 1], late[:, 1]])):
            if B <= A:
                continue
            k = ((early[:, 0] >= A) & (early[:, 1] <= B)).astype(float) + ((late[:, 0] >= A) & (late[:, 1] <= B))
            inside = k > 0
            cap = B - A + r
            if inside.any() and (k[inside] == 2).all() and B - A + 2 * r >= max(fc, r):  # a filter change inside
                cap = B - A + 2 * r - max(fc, r)
            if not inside.any() or k.sum() * (exp + r) <= cap:
                continue  # every exposure fits: implied
            key = tuple(np.flatnonzero(inside)) + tuple(np.flatnonzero(k == 2))
            if key in seen:
                continue  # a wider interval with the same members is weaker
            seen.add(key)
            rows.row("C6 interval capacity", x[ok[inside]], k[inside] * (exp + r), -math.inf, cap)
            n_cuts += 1
    return n_cuts


def start_from_plan(model: ExactModel, problem: PlanningProblem, observations) -> np.ndarray | None:
    """A solution vector of the model placing a rule-abiding plan's exposures (None: not representable).

    Each field of the plan must be one of the model's fields with exactly
    one exposure per filter (what every scheduler of the package returns).
    """
    data = model.data
    cfg = problem.config
    F = data.n_fields
    index = {int(problem.field_ids[row]): f for f, row in enumerate(data.rows)}
    phi = {cfg.filters[0]: 0, cfg.filters[1]: 1}
    v = np.zeros(model.milp.n_vars)
    t = np.repeat(data.lo, 2).astype(float)
    seen = np.zeros(2 * F, bool)
    for o in observations:
        f = index.get(int(o.field_id))
        if f is None or o.filter not in phi or seen[2 * f + phi[o.filter]]:
            return None
        e = 2 * f + phi[o.filter]
        seen[e] = True
        t[e] = o.start
    x = seen.reshape(F, 2).all(axis=1)
    if (seen.reshape(F, 2).any(axis=1) != x).any() or (x & ~data.pairable).any():
        return None
    v[:F] = x
    v[model.off_d:model.off_d + F] = x & (t[1::2] >= t[0::2])
    v[model.off_t:model.off_t + 2 * F] = np.clip(t, np.repeat(data.lo, 2), np.repeat(data.hi, 2))
    for k, (e, w) in enumerate(zip(model.u_exposure, model.u_window)):
        a, b = data.windows[e // 2][w]
        v[model.off_u + k] = float(x[e // 2] and a - 1e-6 <= t[e] and t[e] + cfg.exposure_s <= b + 1e-6)
    for k, (e, e2) in enumerate(model.o_pair):
        v[model.off_o + k] = float(t[e] <= t[e2])
    cells = data.cells
    covered = np.zeros(cells.n_cells)
    cell_of = np.repeat(np.arange(cells.n_cells), np.diff(cells.indptr))
    np.maximum.at(covered, cell_of, x[cells.fields].astype(float))
    v[model.off_y:] = covered
    return v


def solution_parts(model: ExactModel, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[int, tuple[float, float]]]:
    """What a solution ``x`` of the model chose: the fields observed, each exposure's start and window.

    Returns
    -------
    chosen : ndarray of int
        Indices of the observed fields (``y_f = 1``).
    t : ndarray of float
        Start (s from the horizon start) of exposure ``2 f + p`` (filter ``p``), chosen or not.
    windows : dict
        Exposure -> the ``(start, end)`` (s) of the window its ``u`` variable selected.
    """
    F = model.data.n_fields
    chosen = np.flatnonzero(x[:F] > 0.5)
    t = x[model.off_t:model.off_t + 2 * F]
    win = {int(e): model.data.windows[e // 2][w]
           for k, (e, w) in enumerate(zip(model.u_exposure, model.u_window)) if x[model.off_u + k] > 0.5}
    return chosen, t, win


def decode_exact(model: ExactModel, problem: PlanningProblem, x: np.ndarray) -> tuple[Observation, ...]:
    """The plan of a solution: its fields in the solution's order, each exposure as early as the rules allow.

    Re-timing from the solution's order and window choice removes the
    solver's tolerances from the times: every exposure starts at the
    latest of its window's opening, the previous exposure's end plus the
    true overhead and, for a field's second filter, its first plus the
    cadence.  Those are lower bounds the solution's own times satisfy, so
    the re-timed plan stays inside every window the solution used.
    """
    data, cfg = model.data, problem.config
    exp = cfg.exposure_s
    chosen, t, win = solution_parts(model, x)
    exposures = sorted((2 * f + p for f in chosen for p in (0, 1)), key=lambda e: t[e])
    out: list[Observation] = []
    first_at: dict[int, float] = {}
    prev, free = None, 0.0
    for block, e in enumerate(exposures):
        f = e // 2
        a, _ = win.get(e, data.windows[f][0])
        start = max(a, free + (0.0 if prev is None else float(data.overhead[prev, e])))
        if f in first_at:
            start = max(start, first_at[f] + cfg.cadence_s)
        else:
            first_at[f] = start
        row = data.rows[f]
        out.append(Observation(int(problem.field_ids[row]), float(problem.ra[row]), float(problem.dec[row]),
                               cfg.filters[e % 2], float(start), exp, 0))
        prev, free = e, start + exp
    return tuple(out)
