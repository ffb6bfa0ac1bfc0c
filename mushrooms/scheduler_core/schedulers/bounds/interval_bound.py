"""A tighter certified bound: the coverage relaxation that counts the competition for time (V1-V4).

The certified bound of :mod:`.coverage_bound` caps the number of fields of a plan
by the whole observable time (U2), so fields visible at the same hours do
not compete there.  This bound adds one capacity row per time interval
(``docs/design/milp.md``, section "Interval bound", equations V1-V4):

- (V1) a field observable in ``[lo, end]`` (the hull of its widened
  windows) has its earlier exposure inside ``[lo, end - c]`` and its later
  one inside ``[lo + c, end]`` (c the cadence); ``k_f(A, B)`` counts those
  of the two intervals lying inside ``[A, B]``;
- (V2) the exposures inside ``[A, B]`` each take the exposure time and, but
  for the last, the readout: ``Σ_f k_f(A, B) (t_exp + r) z_f <= B - A + r``,
  less ``max(t_filt, r) - r`` when only whole fields are counted (both
  filters inside: at least one filter change);
- (V3) the relaxation: ``max Σ_l w_l y_l`` subject to U2, U3 and every V2
  row, ``z`` binary; every rule-abiding plan is a feasible point;
- (V4) the value: V2 rows are many (every pair of endpoints), so they are
  added by separation, at the incumbent of each solve of V3 with the rows
  found so far; every solve's proven dual bound is a bound (fewer rows is a
  weaker relaxation), and the least of them and of U4 is reported.

A time limit only loosens the bound: it never makes it invalid.

(V8) A sequence of one filter (U5, U6): a field's one exposure lies inside
``[lo, end]``, one role, ``k_f(A, B) ∈ {0, 1}``, and no filter change.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import scipy.sparse as sp

from ...problem import PlanningProblem, UpperBound
from .coverage_bound import BOUND_MIP_GAP, widened_windows, coverage_upper_bound, max_fields, one_visit, pairable_rows, \
    solver_margin
from ..milp.solvers import MilpModel, solve_milp

__all__ = ["field_spans", "interval_rows", "interval_violation", "interval_upper_bound"]

#: Solver statuses whose dual bound is proven (an ``error: ...`` status carries none).
PROVEN = ("optimal", "time_limit", "work_limit", "interrupted")

#: Rows added per separation round, and most rounds.
ROWS_PER_ROUND = 40
MAX_ROUNDS = 12


def field_spans(problem: PlanningProblem, rows: np.ndarray,
                windows: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(V1) ``lo``, ``end`` (s): hull of each field's widened windows that hold one exposure (``windows``: V7)."""
    exp = problem.config.exposure_s
    fid, a, b = widened_windows(problem) if windows is None else windows
    ok = b - a >= exp
    ids = problem.field_ids[rows]
    lo = np.full(ids.size, np.inf)
    end = np.full(ids.size, -np.inf)
    pos = {int(f): i for i, f in enumerate(ids)}
    for f, s, e in zip(fid[ok].tolist(), a[ok].tolist(), b[ok].tolist()):
        i = pos.get(int(f))
        if i is not None:
            lo[i], end[i] = min(lo[i], s), max(end[i], e)
    return lo, end


def bound_windows(problem: PlanningProblem) -> tuple | None:
    """(V7) The outer windows when ``config.bound_refine_ends``, else None (the one-step widening, U1)."""
    if not problem.config.bound_refine_ends:
        return None
    from .outer_windows import refined_windows

    return refined_windows(problem, "outer")


def _intervals(problem: PlanningProblem, rows: np.ndarray, windows: tuple | None = None) -> "_Intervals":
    cfg = problem.config
    lo, end = field_spans(problem, rows, windows)
    return _Intervals(lo, end, cfg.exposure_s, cfg.cadence_s, cfg.slew.readout_s, cfg.filter_change_s,
                      one_visit(problem))


def interval_rows(problem: PlanningProblem, rows: np.ndarray, windows: tuple | None = None) -> "_Intervals":
    """(V1, V2) The interval rows of the fields ``rows`` (``windows``: V7), for a caller separating them itself.

    The answer's ``violation(z)`` gives every row's load minus capacity (s)
    at a point ``z`` over ``rows``, ``row(i, j)`` one row's coefficients and
    right-hand side (the joint bound of several telescopes,
    ``docs/design/telescopes.md`` J7, separates each telescope's rows).
    """
    return _intervals(problem, rows, windows)


class _Intervals:
    """The V2 rows for every (A, B) of the role intervals' endpoints, as (nA, nB) arrays.

    A load ``Σ_f z_f [start_f >= A][stop_f <= B]`` is a dominance count: put
    each z_f at (its start's index, its stop's index) and sum the grid
    from the far corner (suffix sums over A, prefix sums over B).
    """

    def __init__(self, lo: np.ndarray, end: np.ndarray, exp: float, cad: float, r: float, fc: float,
                 single: bool = False) -> None:
        # (V1) the earlier and the later exposure's interval; (V8) one visit: its one exposure's
        self.roles = ((lo, end),) if single else ((lo, end - cad), (lo + cad, end))
        self.A = np.unique(np.concatenate([a for a, _ in self.roles]))
        self.B = np.unique(np.concatenate([b for _, b in self.roles]))
        self.index = [(np.searchsorted(self.A, a), np.searchsorted(self.B, b)) for a, b in self.roles]
        self.whole_index = (np.searchsorted(self.A, lo), np.searchsorted(self.B, end))
        ones = np.ones(lo.size)
        counted = self._load(ones)
        whole = self._count(self.whole_index, ones)  # fields with both exposures inside
        length = self.B[None, :] - self.A[:, None]
        change = (whole > 0.5) & (np.abs(counted - 2 * whole) < 0.5) & (length + 2 * r >= max(fc, r))
        if single:  # (V8) one filter: no filter change
            change = np.zeros_like(change)
        self.cap = length + r - np.where(change, max(fc, r) - r, 0.0)
        self.unit = exp + r
        self.live = (length > 0) & (counted * self.unit > self.cap + 1e-9)  # rows not implied

    def _count(self, index: tuple[np.ndarray, np.ndarray], z: np.ndarray) -> np.ndarray:
        grid = np.zeros((self.A.size, self.B.size))
        np.add.at(grid, index, z)
        return np.cumsum(np.cumsum(grid[::-1], axis=0)[::-1], axis=1)

    def _load(self, z: np.ndarray) -> np.ndarray:
        if len(self.index) == 1:  # (V8) one role
            return self._count(self.index[0], z)
        return self._count(self.index[0], z) + self._count(self.index[1], z)

    def violation(self, z: np.ndarray) -> np.ndarray:
        """(nA, nB) load minus capacity (s) of each row at point z; -inf for implied rows."""
        return np.where(self.live, self._load(z) * self.unit - self.cap, -np.inf)

    def row(self, i: int, j: int) -> tuple[np.ndarray, float]:
        """(V2) coefficients (F,) and right-hand side of row (A_i, B_j)."""
        k = sum(((a >= self.A[i]) & (b <= self.B[j])).astype(float) for a, b in self.roles)
        return k * self.unit, float(self.cap[i, j])


def interval_violation(problem: PlanningProblem, chosen_ids) -> float:
    """Largest V2 violation (s) of a set of fields over the pairable fields; <= 0 for every rule-abiding plan."""
    windows = bound_windows(problem)
    rows = pairable_rows(problem, windows)
    iv = _intervals(problem, rows, windows)
    z = np.isin(problem.field_ids[rows], np.asarray(list(chosen_ids))).astype(float)
    v = iv.violation(z)
    return float(v.max()) if v.size else -math.inf


def interval_upper_bound(problem: PlanningProblem, time_limit_s: float = 2.0) -> UpperBound:
    """Certified coverage bound counting the competition for time (V1-V4); never above U4.

    Parameters
    ----------
    problem : PlanningProblem
    time_limit_s : float
        Budget (s, on ``problem.clock``: wall or work seconds) of all the
        solves; when it runs out the least proven bound so far is returned
        (still an upper bound).

    Returns
    -------
    UpperBound
        Status ``interval`` (V3 solved with no V2 row violated at its
        optimum: the relaxation's optimum), ``interval_dual_bound`` (budget
        or rounds ran out: the least proven bound), both with ``method``
        ``interval``; or U4 itself (``method`` ``online``) when it is not above V.
    """
    from ...sky.cells import merge_cells
    from ..blocks.schedule import shortlist_footprints

    t0, start = time.perf_counter(), problem.clock.mark()
    u4 = coverage_upper_bound(problem)
    windows = bound_windows(problem)  # (V7) the outer windows, or None: the one-step widening
    rows = pairable_rows(problem, windows)
    K = max_fields(problem, rows, windows)
    if rows.size == 0 or K == 0:
        return u4
    iv = _intervals(problem, rows, windows)
    cells = merge_cells(shortlist_footprints(problem.footprints, rows), problem.prob)
    F, C = int(rows.size), cells.n_cells
    cell_of = np.repeat(np.arange(C), np.diff(cells.indptr))
    # variables [z (F) | y (C)]; (U3) y_c - Σ_{f ∋ c} z_f <= 0; (U2) Σ z_f <= K
    base = sp.vstack([
        sp.csr_matrix((np.concatenate([np.ones(C), -np.ones(cell_of.size)]),
                       (np.concatenate([np.arange(C), cell_of]), np.concatenate([F + np.arange(C), cells.fields]))),
                      shape=(C, F + C)),
        sp.csr_matrix((np.ones(F), (np.zeros(F, np.int64), np.arange(F))), shape=(1, F + C)),
    ]).tocsr()
    base_hi = np.concatenate([np.zeros(C), [float(K)]])
    c = np.concatenate([np.zeros(F), cells.weight])  # (V3) max Σ w_c y_c
    integer = np.concatenate([np.ones(F, bool), np.zeros(C, bool)])
    cuts: list[tuple[np.ndarray, float]] = []
    best, status = math.inf, "interval_dual_bound"
    for _ in range(MAX_ROUNDS):
        left = time_limit_s - problem.clock.since(start)  # (A1)
        if left <= 0.05:
            break
        problem.clock.step("bound_round")  # (A3)
        # (V2) the interval rows found so far
        A = sp.vstack([base] + [sp.csr_matrix(np.concatenate([k, np.zeros(C)])[None, :]) for k, _ in cuts]).tocsr()
        hi = np.concatenate([base_hi, [b for _, b in cuts]])
        model = MilpModel(c, A, np.full(hi.size, -np.inf), hi, np.zeros(F + C), np.ones(F + C), integer)
        # the process's thread setting: HiGHS sizes one thread pool per process (solve_milp resets it
        # when the count changes); a failed solve's dual bound is no bound at all
        res = solve_milp(model, "highs", left, mip_gap=BOUND_MIP_GAP, threads=problem.config.threads,
                         clock=problem.clock)
        if res.status in PROVEN and res.bound is not None and math.isfinite(res.bound):
            best = min(best, float(res.bound))  # (V4) every solve's proven bound is a bound
        if res.x is None or res.status not in PROVEN:
            break
        v = iv.violation(np.round(res.x[:F]))
        order = np.argsort(v, axis=None)[::-1][:ROWS_PER_ROUND]
        new = [np.unravel_index(k, v.shape) for k in order if v.flat[k] > 1e-6]
        if not new:
            status = "interval" if res.status == "optimal" else status
            break
        cuts += [iv.row(int(a), int(b)) for a, b in new]
    margin = solver_margin(best, float(cells.weight.sum()))  # (B1) the solver's tolerances
    value = best + margin
    if not value < u4.value:  # never above U4: min(U4, V)
        return dataclasses.replace(u4, runtime_s=time.perf_counter() - t0)
    return UpperBound(value, status, F, K, time.perf_counter() - t0, method="interval", margin=margin)
