"""A certified upper bound on the coverage of any rule-abiding plan.

Every plan the checker accepts observes each of its fields in both filters,
the cadence apart, each exposure inside one of the field's windows, one
exposure at a time with at least the readout between two.  Hence
(``docs/design/milp.md``, section "Certified upper bound", equations U0-U4):

- only *pairable* fields take part: a field whose earliest possible
  exposure start and latest possible one are at least the cadence apart;
- a plan of k fields needs 2k exposures; inside one observable segment of
  length ``T_s`` (union of the pairable fields' windows) at most
  ``floor((T_s + r) / (t_exp + r))`` exposures fit (r = readout, the least
  overhead), so ``k <= K = floor(Σ_s floor((T_s + r) / (t_exp + r)) / 2)``;
- coverage = probability in the union of the k fields.

The bound is an upper bound on the optimum of the maximum coverage problem
``max Σ w_c y_c`` s.t. ``y_c <= Σ_{f ∋ c} z_f``, ``Σ_f z_f <= K`` over the
pairable fields (U0).  By default it is the *online bound* (U4) of the greedy
algorithm (Leskovec et al. 2007, from submodularity): for every greedy
prefix S_i, ``OPT <= f(S_i) + Σ (the K largest marginal gains given S_i)``;
the least over a dozen prefixes is taken, and it is at most the probability
of all pairable fields together.  Hundreds of fields hold some probability,
so solving the relaxation exactly takes seconds to minutes; the online
bound takes a fraction of a second and is within a few per cent of it
(``method="milp"`` solves it, the solver's proven bound is used on a time
limit).

A sequence of one filter (LS4's ``i``, WINTER's ``J``) covers a field with
one exposure: (U5) every field whose widened windows hold one exposure takes
part, and (U6) ``K = Σ_s floor((T_s + r) / (t_exp + r))``, one exposure a field.

The windows used are the problem's, widened by one time step at each end:
visibility windows are found on a time grid and are conservative by less
than one step (see :mod:`..visibility`), so the true windows lie inside the
widened ones.  Not covered: fields the problem dropped for having no
window of one exposure on the grid (their true windows are shorter than
``t_exp + 2 step``).
"""

from __future__ import annotations

import math
import time

import numpy as np
import scipy.sparse as sp

from ...sky.cells import merge_cells
from ...problem import PlanningProblem, UpperBound  # UpperBound is defined beside ScheduleResult, which holds one
from ...sky.windows import union_intervals
from ..milp.solvers import MilpModel, solve_milp

__all__ = ["UpperBound", "one_visit", "pairable_rows", "max_fields", "coverage_upper_bound", "solver_margin", "BOUND_MIP_GAP",
           "HIGHS_PRIMAL_TOL", "ROUNDING_MARGIN"]

#: (B1) The relative MIP gap the bound's solves stop at (HiGHS ``mip_rel_gap``).
BOUND_MIP_GAP = 1e-6
#: (B1) HiGHS's primal feasibility tolerance (its default ``primal_feasibility_tolerance``): how far a row
#: of a solution it accepts may be violated.
HIGHS_PRIMAL_TOL = 1e-7
#: (B2) An exact bound's float rounding (sums of at most ~1e5 weights, each rounded to 2^-53 relative).
ROUNDING_MARGIN = 1e-9


def solver_margin(value: float, total_weight: float) -> float:
    """(B1) What a MILP bound ``value`` (coverage) carries: ``g |v| + tau_p sum_l w_l + 1e-9``.

    ``g`` (:data:`BOUND_MIP_GAP`): a solve stopped at the gap may report its
    incumbent's objective, up to ``g |v|`` below its dual bound;
    ``tau_p`` (:data:`HIGHS_PRIMAL_TOL`): each coverage row ``y_l <= sum z_f``
    may be violated by ``tau_p``, moving ``sum w_l y_l`` by at most
    ``tau_p sum_l w_l``; and the rounding of :data:`ROUNDING_MARGIN`.
    """
    return BOUND_MIP_GAP * abs(float(value)) + HIGHS_PRIMAL_TOL * max(float(total_weight), 0.0) + ROUNDING_MARGIN


def widened_windows(problem: PlanningProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w = problem.windows
    step = problem.config.time_step_s
    a = np.clip(w.start - step, 0.0, problem.horizon_s)
    b = np.clip(w.end + step, 0.0, problem.horizon_s)
    return w.field_ids, a, b


def one_visit(problem: PlanningProblem) -> bool:
    """(U5) The sequence is one filter: one exposure covers a field (F1 with k = 1), no cadence to keep."""
    return len(problem.config.filters) < 2


def pairable_rows(problem: PlanningProblem, windows: tuple | None = None) -> np.ndarray:
    """(U1) Rows of fields whose (widened) windows can hold two exposures the cadence apart.

    (U5) One visit (:func:`one_visit`): every field whose windows hold one exposure.
    ``windows``: ``(field_ids, start, end)`` widened otherwise (the outer windows, V7); default one step (U1).
    """
    cfg = problem.config
    fid, a, b = widened_windows(problem) if windows is None else windows
    ok = b - a >= cfg.exposure_s
    earliest: dict[int, float] = {}
    latest: dict[int, float] = {}
    for f, s, e in zip(fid[ok].tolist(), a[ok].tolist(), b[ok].tolist()):
        earliest[f] = min(earliest.get(f, math.inf), s)
        latest[f] = max(latest.get(f, -math.inf), e - cfg.exposure_s)
    if one_visit(problem):  # (U5) one exposure inside a window covers the field
        good = list(earliest)
    else:
        good = [f for f in earliest if latest[f] - earliest[f] >= cfg.cadence_s - 1e-6]
    return np.flatnonzero(np.isin(problem.field_ids, good))


def max_fields(problem: PlanningProblem, rows: np.ndarray, windows: tuple | None = None) -> int:
    """(U2) K: most fields whose 2 K exposures fit the observable time of these rows (``windows`` as in pairable_rows).

    (U6) One visit: K exposures, one a field.
    """
    cfg = problem.config
    fid, a, b = widened_windows(problem) if windows is None else windows
    sel = np.isin(fid, problem.field_ids[rows]) & (b - a >= cfg.exposure_s)
    if not sel.any():
        return 0
    starts, ends = union_intervals(a[sel], b[sel])
    seg = ends - starts
    r = cfg.slew.readout_s
    n_exp = np.floor((seg + r) / (cfg.exposure_s + r) + 1e-9).sum()
    return int(n_exp) if one_visit(problem) else int(n_exp // 2)  # (U6) one exposure a field; (U2) two


#: The online bound is evaluated at this many greedy prefixes (evenly spaced, plus the full one).
N_CHECKPOINTS = 12


def _online_bound(footprints, prob: np.ndarray, K: int) -> float:
    """(U4) min over greedy prefixes S_i of f(S_i) + the K largest marginal gains given S_i."""
    from ..blocks.prune import greedy_max_coverage

    picked = greedy_max_coverage(footprints, prob, K)
    indptr, indices = footprints.indptr, footprints.indices
    uncovered = np.asarray(prob, float).copy()
    checkpoints = set(np.linspace(0, picked.size, N_CHECKPOINTS + 1).round().astype(int).tolist())
    best = math.inf
    for i in range(picked.size + 1):
        if i in checkpoints:
            gains = footprints.field_probability(uncovered)
            top = np.partition(gains, gains.size - K)[gains.size - K:] if gains.size > K else gains
            best = min(best, float(prob.sum() - uncovered.sum()) + float(top.sum()))
        if i < picked.size:
            k = picked[i]
            uncovered[indices[indptr[k]:indptr[k + 1]]] = 0.0
    return best


def coverage_upper_bound(problem: PlanningProblem, method: str = "online", time_limit_s: float = 30.0,
                         backend: str = "highs") -> UpperBound:
    """Certified upper bound on the coverage any rule-abiding plan reaches (U0-U4).

    Parameters
    ----------
    problem : PlanningProblem
    method : str
        ``online`` (default, fast) or ``milp`` (solve the relaxation); the
        tighter interval bound (V1-V4) is
        :func:`~.interval_bound.interval_upper_bound`.
    time_limit_s : float
        For ``milp``: limit (s) of the solve; when reached, the solver's
        proven dual bound is used (still an upper bound).
    backend : str
        MILP backend (``highs`` by default: the bound must not depend on a licence).

    Returns
    -------
    UpperBound
    """
    from ..blocks.schedule import shortlist_footprints

    t0 = time.perf_counter()
    rows = pairable_rows(problem)
    K = max_fields(problem, rows)
    if rows.size == 0 or K == 0:
        return UpperBound(0.0, "empty", int(rows.size), K, time.perf_counter() - t0)
    fp = shortlist_footprints(problem.footprints, rows)
    everything = problem.footprints.coverage(problem.field_ids[rows], problem.prob)
    if rows.size <= K:
        return UpperBound(everything, "all_fields", int(rows.size), K, time.perf_counter() - t0)
    if method == "online":
        value = _online_bound(fp, problem.prob, K)
        return UpperBound(min(value + ROUNDING_MARGIN, everything), "online", int(rows.size), K,
                          time.perf_counter() - t0, margin=ROUNDING_MARGIN)  # (B2)
    if method != "milp":
        raise ValueError(f"unknown bound method {method!r}")
    cells = merge_cells(fp, problem.prob)
    F, C = int(rows.size), cells.n_cells
    cell_of = np.repeat(np.arange(C), np.diff(cells.indptr))
    # variables [z (F) | y (C)]; (U3) y_c - Σ_{f ∋ c} z_f <= 0; (U2) Σ z_f <= K
    A = sp.vstack([
        sp.csr_matrix((np.concatenate([np.ones(C), -np.ones(cell_of.size)]),
                       (np.concatenate([np.arange(C), cell_of]), np.concatenate([F + np.arange(C), cells.fields]))),
                      shape=(C, F + C)),
        sp.csr_matrix((np.ones(F), (np.zeros(F, np.int64), np.arange(F))), shape=(1, F + C)),
    ]).tocsr()
    c = np.concatenate([np.zeros(F), cells.weight])  # (U0) max Σ w_c y_c
    integer = np.concatenate([np.ones(F, bool), np.zeros(C, bool)])
    model = MilpModel(c, A, np.full(C + 1, -np.inf), np.concatenate([np.zeros(C), [float(K)]]),
                      np.zeros(F + C), np.ones(F + C), integer)
    res = solve_milp(model, backend, time_limit_s, mip_gap=BOUND_MIP_GAP, clock=problem.clock)
    if res.status in ("optimal", "time_limit", "work_limit", "interrupted") and res.bound is not None \
            and math.isfinite(res.bound):
        value, status = float(res.bound), "optimal" if res.status == "optimal" else "dual_bound"
    else:
        value, status = everything, "all_fields"
    margin = solver_margin(value, float(cells.weight.sum()))  # (B1)
    return UpperBound(min(value + margin, everything), status, F, K, time.perf_counter() - t0, method="milp",
                      margin=margin)
