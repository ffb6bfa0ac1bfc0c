"""The certified bound on a joint plan's coverage (``docs/design/telescopes.md``, J7, J8).

(J7) Every telescope keeps the relaxation its own bound uses
(``docs/design/milp.md``, U1-U3 and V1-V2) on its own field variables
``z_τ``; the telescopes are coupled only through the cells over the union
of their pairable fields:

    B_joint = max Σ_l w_l y_l   s.t.  y_l <= Σ_τ Σ_{f ∈ S_{l,τ}} z_{τ,f},  y_l <= 1,
                                      (U2, V2 of τ) on z_τ for every τ,  z binary

A rule-abiding joint plan gives each telescope a rule-abiding plan, whose
fields satisfy that telescope's U2 and V2 rows, and covers a cell only
through some telescope's field: it is a feasible point.  V2 rows are
separated as in the interval bound (V4), per telescope, at each solve's
incumbent; every solve's proven dual bound is a bound, plus its margin (B1).

(J8) The published bound is ``min(B_joint, Σ_τ U4_τ, Σ_l w_l)``: U4_τ bounds
τ's share, the union is at most the sum of the shares, and at most all the
probability of the pairable fields.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.sparse as sp

from ...budget import new_clock
from ...problem import PlanningProblem, UpperBound
from ..blocks.schedule import shortlist_footprints
from ..bounds.coverage_bound import BOUND_MIP_GAP, ROUNDING_MARGIN, coverage_upper_bound, max_fields, \
    one_visit, pairable_rows, solver_margin
from ..bounds.interval_bound import PROVEN, ROWS_PER_ROUND, MAX_ROUNDS, bound_windows, interval_rows
from ..milp.rows import Columns, RowBuilder
from ..milp.solvers import MilpModel, solve_milp
from .cells import joint_cells, telescope_names

__all__ = ["JointBound", "joint_upper_bound", "quick_joint_bound"]


@dataclass(frozen=True)
class JointBound:
    """(J8) The published bound on the union coverage of any rule-abiding joint plan, and its three terms.

    Attributes
    ----------
    value : float
        ``min(joint, sum_of_telescopes, total)``.
    joint : float
        B_joint (J7) plus its margin (B1); ``inf`` when not computed.
    sum_of_telescopes : float
        Σ_τ U4_τ.
    total : float
        Probability of all the telescopes' pairable fields together (plus rounding).
    status : str
        ``interval`` (J7 solved with no row violated), ``interval_dual_bound``
        (budget or rounds ran out) or ``not_solved``.
    per_telescope : tuple of UpperBound
        Each telescope's U4 (a one-visit rule: with U5-U6).
    margin : float
        What ``joint`` carries above the solver's bound (B1).
    """

    value: float
    joint: float
    sum_of_telescopes: float
    total: float
    status: str
    per_telescope: tuple[UpperBound, ...]
    margin: float = 0.0

    @property
    def method(self) -> str:
        """Which term is the bound: ``joint``, ``sum`` or ``total``."""
        if self.value == self.joint:
            return "joint"
        return "sum" if self.value == self.sum_of_telescopes else "total"


class _Part:
    """One telescope in the relaxation: its pairable rows, K (U2) and interval rows (V1-V2).

    A one-visit rule (one filter) has no pair: its rows are the fields whose
    widened windows hold one exposure (U5), K the exposures its observable
    time holds (U6) and its interval rows have one role a field (V8)
    (``docs/design/milp.md``).
    """

    def __init__(self, problem: PlanningProblem) -> None:
        self.one_visit = one_visit(problem)
        self.rows, self.K, self.intervals = np.zeros(0, np.int64), 0, None
        self.cuts: list[tuple[np.ndarray, float]] = []
        if problem.field_ids.size == 0:
            return
        windows = bound_windows(problem)
        rows = pairable_rows(problem, windows)  # (U1), or (U5) for one visit
        K = max_fields(problem, rows, windows) if rows.size else 0  # (U2), or (U6)
        if K > 0 and rows.size:
            self.rows, self.K = rows, K
            self.intervals = interval_rows(problem, rows, windows)  # (V1-V2), or (V8)

    def own_bound(self, problem: PlanningProblem) -> UpperBound:
        """τ's bound on its share: U4 (with U5-U6 for a one-visit rule)."""
        if problem.field_ids.size == 0 or self.rows.size == 0:
            return UpperBound(0.0, "empty", 0, 0, 0.0)
        return coverage_upper_bound(problem)


def _model(parts: list[_Part], cells, names: Sequence[str]) -> tuple[MilpModel, list]:
    """(J7) The relaxation with the V2 rows found so far; and each part's z columns."""
    cols = Columns()
    zs = [cols.family(f"{name}.z", part.rows.size) for name, part in zip(names, parts)]
    C = cells.n_cells
    y = cols.family("y", C)
    rows = RowBuilder()
    stacked = np.concatenate([z.columns for z in zs])
    cell_of = np.repeat(np.arange(C), np.diff(cells.indptr))
    # (J7) y_l - Σ_τ Σ_{f ∈ S_{l,τ}} z_{τ,f} <= 0
    rows.block("J7 coverage through any telescope", C,
               [(np.arange(C), y[np.arange(C)], 1.0), (cell_of, stacked[cells.fields], -1.0)], -np.inf, 0.0)
    for name, part, z in zip(names, parts, zs):
        if part.rows.size == 0:
            continue
        rows.prefix = f"{name}: "
        # (U2) of τ: Σ_f z_{τ,f} <= K_τ
        rows.row("U2 most fields", z.columns, np.ones(z.size), -np.inf, float(part.K))
        for coef, rhs in part.cuts:  # (V2) of τ, the rows found so far
            rows.row("V2 interval capacity", z.columns, coef, -np.inf, rhs)
        rows.prefix = ""
    A, lo, hi = rows.matrix(cols.n)
    c = np.zeros(cols.n)
    c[y.columns] = cells.weight
    integer = np.zeros(cols.n, bool)
    integer[stacked] = True
    return MilpModel(c, sp.csr_matrix(A), lo, hi, np.zeros(cols.n), np.ones(cols.n), integer, rows.blocks(),
                     cols.families()), zs


def _separate(parts: list[_Part], zs, x: np.ndarray) -> bool:
    """(V4) Add each telescope's most violated V2 rows at the incumbent ``x``; False when none is violated."""
    found = False
    for part, z in zip(parts, zs):
        if part.intervals is None:
            continue
        v = part.intervals.violation(np.round(x[z.columns]))
        order = np.argsort(v, axis=None)[::-1][:ROWS_PER_ROUND]
        new = [np.unravel_index(k, v.shape) for k in order if v.flat[k] > 1e-6]
        part.cuts += [part.intervals.row(int(a), int(b)) for a, b in new]
        found = found or bool(new)
    return found


def joint_upper_bound(problems: Sequence[PlanningProblem], weight: np.ndarray | None = None,
                      time_limit_s: float | None = None, names: Sequence[str] | None = None) -> JointBound:
    """(J7, J8) The certified bound on the union coverage of every rule-abiding joint plan.

    Parameters
    ----------
    problems : sequence of PlanningProblem
        One per telescope, on the same map.
    weight : numpy.ndarray, optional
        Pixel weights (default the map's probability).
    time_limit_s : float, optional
        Budget (s, work seconds when deterministic) of J7's solves; default
        the largest ``bound_time_limit_s`` of the telescopes.  0: J7 is not
        solved (the bound is the least of the other two terms).
    names : sequence of str, optional
        Telescope names (the model's row and column prefixes).
    """
    w = problems[0].prob if weight is None else np.asarray(weight, float)
    names = list(telescope_names(problems, names))
    parts = [_Part(p) for p in problems]
    u4 = tuple(part.own_bound(p) for p, part in zip(problems, parts))
    total_u4 = float(sum(b.value for b in u4))
    prints = [shortlist_footprints(p.footprints, part.rows) for p, part in zip(problems, parts)]
    cells = joint_cells(prints, w, problems[0].footprints.nside).cells
    total = float(cells.weight.sum()) + ROUNDING_MARGIN  # (B2)
    limit = max(p.config.bound_time_limit_s for p in problems) if time_limit_s is None else float(time_limit_s)
    best, status = math.inf, "not_solved"
    clock = new_clock(all(p.config.deterministic for p in problems))
    start = clock.mark()
    for _ in range(MAX_ROUNDS if cells.n_cells and limit > 0 else 0):
        left = limit - clock.since(start)
        if left <= 0.05:
            break
        clock.step("bound_round")  # (A3)
        model, zs = _model(parts, cells, names)
        res = solve_milp(model, "highs", left, mip_gap=BOUND_MIP_GAP, threads=problems[0].config.threads,
                         clock=clock)
        if res.status in PROVEN and res.bound is not None and math.isfinite(res.bound):
            best = min(best, float(res.bound))  # every solve's proven bound is a bound (V4)
            status = "interval_dual_bound"
        if res.x is None or res.status not in PROVEN:
            break
        if not _separate(parts, zs, res.x):
            status = "interval" if res.status == "optimal" else status
            break
    margin = solver_margin(best, float(cells.weight.sum())) if math.isfinite(best) else 0.0  # (B1)
    joint = best + margin
    value = min(joint, total_u4, total)  # (J8)
    return JointBound(value, joint, total_u4, total, status, u4, margin)


def quick_joint_bound(problems: Sequence[PlanningProblem], weight: np.ndarray | None = None) -> JointBound:
    """(J8) without J7: ``min(Σ_τ U4_τ, total)``, no cells, no solve (the service's parts, J9).

    ``total`` is the weight of the pixels any telescope's pairable (one-visit:
    observable) fields cover, plus the rounding margin: the same term as
    :func:`joint_upper_bound`'s, from the footprints' union instead of the
    cells.  Certified like it; looser only by B_joint.
    """
    from .cells import covered_pixels

    w = problems[0].prob if weight is None else np.asarray(weight, float)
    parts = [_Part(p) for p in problems]
    u4 = tuple(part.own_bound(p) for p, part in zip(problems, parts))
    mask = np.zeros(w.size, bool)
    for p, part in zip(problems, parts):
        mask[covered_pixels(p, p.field_ids[part.rows])] = True
    total = float(w[mask].sum()) + ROUNDING_MARGIN
    total_u4 = float(sum(b.value for b in u4))
    return JointBound(min(total_u4, total), math.inf, total_u4, total, "not_solved", u4, 0.0)
