"""The exact continuous-time model of the full planning rules, for reduced instances.

Not a scheduler (it lives in evaluation and never in the planning path; the
model itself is :mod:`mushrooms.scheduler_core.schedulers.portfolio.continuous`, which the
hybrid's large-neighbourhood stage also solves on slices of the night):
it answers "what is the best plan any scheduler could find on this
problem?" on a few tens of fields, so that the distance from a plan to the
certified bound splits into *bound slack* (bound − optimum) and *optimiser
loss* (optimum − plan).  ``docs/design/milp.md``, section "Exact model",
equations C0–C6.

The model's rules and why an integral solution is exactly a rule-abiding
plan are in that module's docstring; here it is solved whole, started from
the schedulers' plans, and its optimum is the optimum of the rules on the
problem's windows.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from ..scheduler_core.problem import PlanningProblem, ScheduleResult
from ..scheduler_core.schedulers.portfolio.continuous import (INTEGRAL_TOL, ExactData, ExactModel, build_exact_model,
                                                    decode_exact, exact_data, start_from_plan)
from ..scheduler_core.schedulers.milp.solvers import SolveResult, solve_milp

__all__ = ["ExactData", "ExactModel", "ExactResult", "exact_data", "build_exact_model", "start_from_plan",
           "decode_exact", "solve_exact", "INTEGRAL_TOL"]


@dataclass(frozen=True)
class ExactResult:
    """What :func:`solve_exact` found.

    Attributes
    ----------
    result : ScheduleResult
        The plan (solver ``exact:highs``), status ``optimal`` or ``time_limit``.
    optimum : float or None
        The coverage of the plan (the model's objective, cell weights).
    bound : float or None
        The solver's proven bound on the optimum (equal to ``optimum`` when proven).
    gap : float or None
        Relative gap.
    size : dict
        Model size (``vars``, ``int_vars``, ``rows``, ``nonzeros``, ``cuts``, ``pairs``).
    """

    result: ScheduleResult
    optimum: float | None
    bound: float | None
    gap: float | None
    size: dict = field(default_factory=dict)

    @property
    def proven(self) -> bool:
        """True when the optimum is proven (status ``optimal``)."""
        return self.result.status == "optimal"


def solve_exact(problem: PlanningProblem, time_limit_s: float = 60.0, threads: int = 1,
                starts: tuple = (), mip_gap: float = 1e-6) -> ExactResult:
    """Solve the exact model of ``problem`` with HiGHS, optionally from rule-abiding plans.

    Parameters
    ----------
    problem : PlanningProblem
        A reduced problem (a few tens of fields).
    time_limit_s : float
        Solver limit (s); on reaching it the incumbent and the proven bound come back.
    threads : int
        Solver threads.
    starts : tuple of sequences of Observation
        Plans to start from (the best representable one is given to the solver).
    mip_gap : float
        Relative gap at which the solve stops (default: proven to 1e-6).

    Returns
    -------
    ExactResult
    """
    t0 = time.perf_counter()
    model = build_exact_model(problem)
    start = None
    best = -math.inf
    for obs in starts:
        v = start_from_plan(model, problem, obs)
        if v is not None and float(model.milp.c @ v) > best:
            start, best = v, float(model.milp.c @ v)
    res: SolveResult = solve_milp(model.milp, "highs", time_limit_s, mip_gap=mip_gap, threads=threads, start=start)
    observations = decode_exact(model, problem, res.x) if res.x is not None else ()
    size = dict(model.milp.size(), cuts=model.n_cuts, pairs=int(model.o_pair.shape[0]))
    result = ScheduleResult(observations=observations, solver="exact:highs", status=res.status,
                            mip_gap=res.gap, runtime_s=time.perf_counter() - t0, mip_bound=res.bound,
                            details={"model_size": size, "solve_s": res.runtime_s})
    return ExactResult(result, res.objective, res.bound, res.gap, size)
