"""A thin MILP adapter: one backend-neutral model, two solvers (HiGHS, Gurobi).

The block-division model is built once as a :class:`MilpModel` (sparse
constraint matrix, row and column bounds, integrality, objective) and handed
to :func:`solve_milp`, which runs HiGHS (``highspy``, the default) or Gurobi
(``gurobipy``).  Both report the same :class:`SolveResult`: status, solution,
objective, best bound, relative gap, time to the first incumbent and time to
a 1 % gap (from the solvers' callbacks), and the runtime.

Gurobi is used when asked for (``backend="gurobi"``) or, with
``backend="auto"``, when a full licence is present.  The pip wheel's
size-limited licence refuses models over 2000 variables or constraints; the
run then falls back to HiGHS with one log line instead of failing.

The model and a solve's result are :mod:`.model`'s; here, the two backends
and the choice between them.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from ...budget import Clock, solve_work, wall_stop
from ...problem import StopCheck
from .model import MilpModel, SolveResult, relative_gap

__all__ = ["MilpModel", "SolveResult", "solve_milp", "highs_lp", "gurobi_fully_licensed", "resolve_backend", "relative_gap"]

log = logging.getLogger(__name__)

#: Gap at which the "time to 1 % gap" is recorded.
REPORT_GAP = 0.01
#: Variable/constraint limit of Gurobi's size-limited (pip) licence.
GUROBI_PIP_LIMIT = 2000

#: HiGHS keeps one thread pool per process, sized by the first solve's ``threads``; a later solve asking for
#: another count fails (status "Not Set", no solution, a dual bound of 0).  The count the pool was sized
#: for, and the lock around resizing it: a solve asking for another count resets the pool first.
_highs_pool = {"threads": None}
_highs_pool_lock = threading.Lock()


class _Progress:
    """Incumbent/bound bookkeeping shared by the backends' callbacks."""

    def __init__(self, t0: float) -> None:
        self.t0 = t0
        self.first: float | None = None
        self.at_gap: float | None = None
        self.trace: list[tuple[float, float, float]] = []
        self.bound = math.inf  # the latest dual bound reported

    def update(self, objective: float, bound: float) -> None:
        # the solvers report "none yet" as +-inf (HiGHS) or +-1e100 (Gurobi)
        objective = objective if abs(objective) < 1e99 else math.inf
        bound = bound if abs(bound) < 1e99 else math.inf
        if math.isfinite(bound):
            self.bound = float(bound)
        now = time.perf_counter() - self.t0
        if math.isfinite(objective) and self.first is None:
            self.first = now
        gap = relative_gap(objective, bound) if math.isfinite(objective) else None
        if gap is not None and gap <= REPORT_GAP and self.at_gap is None:
            self.at_gap = now
        if math.isfinite(objective) and (not self.trace or self.trace[-1][1] != objective):
            self.trace.append((now, float(objective), float(bound)))


def _stop_check(progress: _Progress, should_stop: StopCheck | None, cutoff: float | None
                ) -> tuple[Callable[[], bool], list[bool]]:
    """The backends' stop test (the caller's ``should_stop``, or the bound below ``cutoff``) and its cutoff flag."""
    cut = [False]

    def stop_now() -> bool:
        if cutoff is not None and progress.bound < cutoff:
            cut[0] = True
            return True
        return should_stop is not None and bool(should_stop())

    return stop_now, cut


def solve_milp(
    model: MilpModel,
    backend: str = "highs",
    time_limit_s: float = 30.0,
    mip_gap: float = 0.01,
    threads: int = 0,
    should_stop: StopCheck | None = None,
    start: np.ndarray | None = None,
    abs_gap: float = 0.0,
    cutoff: float | None = None,
    clock: Clock | None = None,
) -> SolveResult:
    """Solve a :class:`MilpModel` with HiGHS or Gurobi.

    Parameters
    ----------
    model : MilpModel
        The model (maximisation).
    backend : str
        ``highs``, ``gurobi`` or ``auto`` (Gurobi when fully licensed).
    time_limit_s : float
        Limit (s): wall time, or work seconds on a work ``clock``.
    mip_gap : float
        Relative gap at which to stop.
    threads : int
        Solver threads; 0 lets the solver choose.
    should_stop : callable, optional
        Polled from the solver's callbacks; True interrupts the solve (the
        incumbent, if any, is kept; status ``interrupted``).
    start : numpy.ndarray, optional
        A feasible (or partial) solution to start from.
    abs_gap : float
        Absolute gap (objective units) at which to stop as well: a caller
        that only wants a solution better than its start by more than this
        (e.g. ``min_gain``) stops as soon as the bound proves there is none
        (V6), instead of at the time limit.  0: the relative gap alone.
    cutoff : float, optional
        Stop (status ``cutoff``) as soon as the solver's bound proves no
        solution reaches this objective: a stage that only matters when it
        beats a plan already found stops once its own relaxation shows it
        cannot.  The incumbent, if any, is returned.
    clock : Clock, optional
        On a work clock (:mod:`..budget`, A2, A4) the limit is work seconds,
        one thread, and the clock is charged the solve's work.

    Returns
    -------
    SolveResult
    """
    if backend not in ("auto", "highs", "gurobi"):
        raise ValueError(f"unknown MILP backend {backend!r}")
    backend = resolve_backend(backend)
    result = None
    args = (model, time_limit_s, mip_gap, threads, should_stop, start, abs_gap, cutoff, clock)
    if backend == "gurobi":
        try:
            result = _solve_gurobi(*args)
        except _GurobiUnavailable as exc:
            log.warning("Gurobi unavailable (%s); solving with HiGHS", exc)
            result = _solve_highs(*args)
            result.note = f"gurobi fallback: {exc}"
    if result is None:
        result = _solve_highs(*args)
    if cutoff is not None and result.bound is not None and result.bound < cutoff:
        result.status = "cutoff"  # proven before any callback (presolve, the root): the same answer
    return result


# --------------------------------------------------------------------- HiGHS

def _solve_highs(model: MilpModel, time_limit_s: float, mip_gap: float, threads: int,
                 should_stop: StopCheck | None, start: np.ndarray | None, abs_gap: float = 0.0,
                 cutoff: float | None = None, clock: Clock | None = None) -> SolveResult:
    import highspy

    t0 = time.perf_counter()
    work = solve_work(clock, model.A.nnz, model.n_rows + model.n_vars, time_limit_s)
    if work is not None:  # (A4) one thread: HiGHS's search, and where it checks its limits, depend on the count
        threads, time_limit_s = 1, work.wall_guard_s
    with _highs_pool_lock:
        if _highs_pool["threads"] not in (None, int(threads)):
            # a sequential change of the thread count (tests, benchmarks): the one config of a service
            # never changes it, so no solve is running in another thread when this happens
            log.debug("HiGHS thread pool: %s -> %s thread(s), resetting it", _highs_pool["threads"], threads)
            highspy.Highs.resetGlobalScheduler(True)
        _highs_pool["threads"] = int(threads)
    h = highspy.Highs()
    h.setOptionValue("output_flag", False)
    h.setOptionValue("time_limit", float(max(time_limit_s, 0.01)))
    h.setOptionValue("mip_rel_gap", float(mip_gap))
    if abs_gap > 0:
        h.setOptionValue("mip_abs_gap", float(abs_gap))
    h.setOptionValue("random_seed", 0)
    if threads > 0:
        h.setOptionValue("threads", int(threads))
    h.passModel(highs_lp(model, highspy))
    if start is not None:
        sol = highspy.HighsSolution()
        sol.col_value = list(np.asarray(start, float))
        sol.value_valid = True
        h.setSolution(sol)

    progress = _Progress(t0)
    interrupted = [False]
    stop_now, cut = _stop_check(progress, should_stop, cutoff)

    def on_improving(event) -> None:
        out = event.data_out
        progress.update(out.mip_primal_bound if math.isfinite(out.mip_primal_bound)
                        else out.objective_function_value, out.mip_dual_bound)

    def on_interrupt(event) -> None:
        out = event.data_out
        progress.update(out.mip_primal_bound, out.mip_dual_bound)
        if (work is not None and work.reached()) or stop_now():  # (A2) the work limit, at a check HiGHS makes
            interrupted[0] = True
            event.interrupt()

    h.cbMipImprovingSolution += on_improving
    h.cbMipInterrupt += on_interrupt
    h.run()
    runtime = time.perf_counter() - t0
    ms = h.getModelStatus()
    info = h.getInfo()
    if work is not None:  # (A2) its checks and, now known, its LP iterations
        work.charge(iterations=max(int(info.simplex_iteration_count), 0))
    sol = h.getSolution()
    MS = highspy.HighsModelStatus
    has_x = info.primal_solution_status == highspy.SolutionStatus.kSolutionStatusFeasible
    x = np.asarray(sol.col_value, float) if has_x else None
    objective = float(info.objective_function_value) if has_x else None
    bound = float(info.mip_dual_bound) if math.isfinite(info.mip_dual_bound) else None
    status = _highs_status(h, ms, MS, cut[0], work is not None and work.stopped, interrupted[0], clock)
    if status == "optimal" and bound is None and objective is not None:
        bound = objective
    if objective is not None:
        progress.update(objective, bound if bound is not None else math.inf)
    return SolveResult(
        backend="highs", status=status, x=x, objective=objective, bound=bound,
        gap=relative_gap(objective, bound), runtime_s=runtime,
        time_to_first_s=progress.first if x is not None else None,
        time_to_gap_s=progress.at_gap, progress=progress.trace,
    )


def _highs_status(h: Any, ms: Any, MS: Any, cut: bool, work_stopped: bool, interrupted: bool,
                  clock: Clock | None) -> str:
    """The :class:`SolveResult` status of a HiGHS run ending in model status ``ms``."""
    if cut:
        return "cutoff"
    if ms == MS.kOptimal:
        return "optimal"
    if ms == MS.kTimeLimit:
        return wall_stop(clock)
    if work_stopped:
        return "work_limit"
    if ms == MS.kInterrupt or interrupted:
        return "interrupted"
    if ms in (MS.kInfeasible, MS.kUnboundedOrInfeasible):
        return "infeasible"
    return f"error: {h.modelStatusToString(ms)}"


def highs_lp(model: MilpModel, highspy: Any) -> Any:
    """The model as HiGHS's ``highspy.HighsLp`` (maximisation, column-wise matrix); ``highspy`` the module."""
    lp = highspy.HighsLp()
    lp.num_col_ = model.n_vars
    lp.num_row_ = model.n_rows
    lp.col_cost_ = np.asarray(model.c, float)
    lp.col_lower_ = np.asarray(model.col_lo, float)
    lp.col_upper_ = np.asarray(model.col_hi, float)
    lp.row_lower_ = np.where(np.isfinite(model.row_lo), model.row_lo, -highspy.kHighsInf)
    lp.row_upper_ = np.where(np.isfinite(model.row_hi), model.row_hi, highspy.kHighsInf)
    lp.sense_ = highspy.ObjSense.kMaximize
    csc = sp.csc_matrix(model.A)
    csc.sort_indices()
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.num_col_ = model.n_vars
    lp.a_matrix_.num_row_ = model.n_rows
    lp.a_matrix_.start_ = csc.indptr.astype(np.int32)
    lp.a_matrix_.index_ = csc.indices.astype(np.int32)
    lp.a_matrix_.value_ = csc.data.astype(float)
    lp.integrality_ = [highspy.HighsVarType.kInteger if i else highspy.HighsVarType.kContinuous
                       for i in model.integer]
    return lp


# -------------------------------------------------------------------- Gurobi

class _GurobiUnavailable(RuntimeError):
    """gurobipy missing, no licence, or the model exceeds a size-limited licence."""


def _gurobi_env():
    try:
        import gurobipy as gp
    except ImportError as exc:  # pragma: no cover - gurobipy is a dependency here
        raise _GurobiUnavailable("gurobipy is not installed") from exc
    try:
        env = gp.Env(empty=True)
        env.setParam("OutputFlag", 0)
        env.start()
    except gp.GurobiError as exc:
        raise _GurobiUnavailable(f"no licence ({exc})") from exc
    return gp, env


def _licence_file_present() -> bool:
    """True when a Gurobi licence file exists where Gurobi looks for one."""
    import os
    from pathlib import Path

    env = os.environ.get("GRB_LICENSE_FILE")
    if env:
        return True  # Gurobi uses it (and reports a bad one itself)
    places = [Path.home(), Path("/opt/gurobi"), Path("/Library/gurobi"), Path("C:/gurobi")]
    return any((p / "gurobi.lic").is_file() for p in places)


def resolve_backend(backend: str) -> str:
    """``auto`` -> ``gurobi`` when fully licensed, else ``highs``; other names unchanged."""
    if backend == "auto":
        return "gurobi" if gurobi_fully_licensed() else "highs"
    return backend


def gurobi_fully_licensed() -> bool:
    """True when Gurobi runs here without the pip licence's size limit.

    Without a licence file (``$GRB_LICENSE_FILE``, or ``gurobi.lic`` in
    Gurobi's default places: the home directory, ``/opt/gurobi``,
    ``/Library/gurobi``, ``C:\\gurobi``) only the pip wheel's size-limited
    licence can exist, so False comes back without importing gurobipy
    (which takes seconds).  Otherwise it probes with an empty model one
    variable over the size limit.
    """
    if not _licence_file_present():
        return False
    try:
        gp, env = _gurobi_env()
    except _GurobiUnavailable:
        return False
    try:
        with gp.Model(env=env) as m:
            m.addMVar(GUROBI_PIP_LIMIT + 1)
            m.optimize()
        return True
    except gp.GurobiError:
        return False
    finally:
        env.dispose()


def _solve_gurobi(model: MilpModel, time_limit_s: float, mip_gap: float, threads: int,
                  should_stop: StopCheck | None, start: np.ndarray | None, abs_gap: float = 0.0,
                  cutoff: float | None = None, clock: Clock | None = None) -> SolveResult:
    gp, env = _gurobi_env()
    GRB = gp.GRB
    t0 = time.perf_counter()
    work = solve_work(clock, model.A.nnz, model.n_rows + model.n_vars, time_limit_s)
    progress = _Progress(t0)
    interrupted = [False]
    stop_now, cut = _stop_check(progress, should_stop, cutoff)
    try:
        m = gp.Model(env=env)
        m.Params.TimeLimit = float(max(time_limit_s, 0.01))
        m.Params.MIPGap = float(mip_gap)
        if abs_gap > 0:
            m.Params.MIPGapAbs = float(abs_gap)
        m.Params.Seed = 0
        if threads > 0:
            m.Params.Threads = int(threads)
        if work is not None:  # (A2) Gurobi's own deterministic work units, one thread (A4), the wall guard (A5)
            m.Params.WorkLimit, m.Params.Threads, m.Params.TimeLimit = max(time_limit_s, 0.0), 1, work.wall_guard_s
        vtype = np.where(model.integer, GRB.INTEGER, GRB.CONTINUOUS)
        lb = np.where(np.isfinite(model.col_lo), model.col_lo, -GRB.INFINITY)
        ub = np.where(np.isfinite(model.col_hi), model.col_hi, GRB.INFINITY)
        x = m.addMVar(model.n_vars, lb=lb, ub=ub, vtype=vtype)
        m.setObjective(np.asarray(model.c, float) @ x, GRB.MAXIMIZE)
        A = sp.csr_matrix(model.A)
        eq = np.isfinite(model.row_lo) & (model.row_lo == model.row_hi)
        lo = np.isfinite(model.row_lo) & ~eq
        hi = np.isfinite(model.row_hi) & ~eq
        if eq.any():
            m.addMConstr(A[eq], x, "=", model.row_lo[eq])
        if lo.any():
            m.addMConstr(A[lo], x, ">", model.row_lo[lo])
        if hi.any():
            m.addMConstr(A[hi], x, "<", model.row_hi[hi])
        if start is not None:
            x.Start = np.asarray(start, float)

        def callback(cb_model, where) -> None:
            if where == GRB.Callback.MIP:
                progress.update(cb_model.cbGet(GRB.Callback.MIP_OBJBST),
                                cb_model.cbGet(GRB.Callback.MIP_OBJBND))
            elif where == GRB.Callback.MIPSOL:
                progress.update(cb_model.cbGet(GRB.Callback.MIPSOL_OBJBST),
                                cb_model.cbGet(GRB.Callback.MIPSOL_OBJBND))
            if where in (GRB.Callback.MIP, GRB.Callback.MIPNODE, GRB.Callback.MIPSOL) and stop_now():
                interrupted[0] = True
                cb_model.terminate()

        try:
            m.optimize(callback)
        except gp.GurobiError as exc:
            if exc.errno in (GRB.Error.SIZE_LIMIT_EXCEEDED, GRB.Error.NO_LICENSE):
                raise _GurobiUnavailable(
                    f"licence refuses a model of {model.n_vars} variables and {m.NumConstrs} constraints"
                    f" (error {exc.errno})") from exc
            raise
        runtime = time.perf_counter() - t0
        if work is not None:
            work.charge(gurobi_work=m.Work)
        st = m.Status
        has_x = m.SolCount > 0
        xv = np.asarray(x.X, float) if has_x else None
        objective = float(m.ObjVal) if has_x else None
        bound = float(m.ObjBound) if has_x or st == GRB.OPTIMAL else None
        status = _gurobi_status(GRB, st, cut[0], interrupted[0], clock)
        if objective is not None:
            progress.update(objective, bound if bound is not None else math.inf)
        m.dispose()
    finally:
        env.dispose()
    return SolveResult(
        backend="gurobi", status=status, x=xv, objective=objective, bound=bound,
        gap=relative_gap(objective, bound), runtime_s=runtime,
        time_to_first_s=progress.first if xv is not None else None,
        time_to_gap_s=progress.at_gap, progress=progress.trace,
    )


def _gurobi_status(GRB: Any, st: int, cut: bool, interrupted: bool, clock: Clock | None) -> str:
    """The :class:`SolveResult` status of a Gurobi run ending in status ``st``."""
    if cut:
        return "cutoff"
    if st == GRB.OPTIMAL:
        return "optimal"
    if st == GRB.TIME_LIMIT:
        return wall_stop(clock)
    if st == GRB.WORK_LIMIT:
        return "work_limit"
    if st == GRB.INTERRUPTED or interrupted:
        return "interrupted"
    if st in (GRB.INFEASIBLE, GRB.INF_OR_UNBD):
        return "infeasible"
    return f"error: gurobi status {st}"
