"""One coordinated plan for several telescopes on one map: :func:`joint_schedule` (``docs/design/telescopes.md``, J6).

The plan, within one budget of work seconds (``[scheduler] deterministic``:
every stage on a work clock, so the plan does not depend on the load):

1. each telescope alone (:func:`~.ascent.plan_alone`, its own
   ``time_limit_s``): the uncoordinated plans, and the start of the ascent;
2. the coordinate ascent (:func:`~.ascent.coordinate_ascent`) from the best
   of them, with what is left of the budget after the joint model's share;
3. the joint model (:mod:`.model`, J1-J4) when it fits: at most
   :data:`JOINT_MAX_PAIRS` binaries and :data:`MIN_JOINT_S` of budget left,
   started from the ascent's plans (each mapped on its telescope's grid);
   its plan replaces the ascent's only when its union is larger.

A telescope with no candidate (no window) gets an empty schedule; with
fewer than two telescopes observing, the one that can plans alone.  The
result carries the joint metrics and the certified bound (:mod:`.bound`, J8).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...budget import new_clock
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from ..milp.solvers import resolve_backend, solve_milp
from .ascent import coordinate_ascent, masked, nothing, plan_alone, union_of
from .bound import JointBound, joint_upper_bound
from .cells import JointMetrics, joint_metrics, telescope_names
from .model import build_joint_model, decode_joint, joint_instance, joint_start, reweighted

__all__ = ["JointResult", "joint_schedule", "JOINT_BUDGET_FACTOR", "JOINT_MAX_PAIRS", "MIN_JOINT_S",
           "JOINT_SHARE"]

#: The joint budget, when not given: this many times the sum of the telescopes' ``time_limit_s``.
JOINT_BUDGET_FACTOR = 3.0
#: (J6) The joint model is solved only with at most this many binaries (eligible pairs of all telescopes).
JOINT_MAX_PAIRS = 60_000
#: (J6) ... and at least this much budget (s) left for it.
MIN_JOINT_S = 0.5
#: The joint model's share of the budget left after the telescopes' plans alone (the ascent gets the rest).
JOINT_SHARE = 0.5


@dataclass(frozen=True)
class JointResult:
    """A coordinated plan: one schedule per telescope, the joint metrics and the bound.

    Attributes
    ----------
    schedules : tuple of ScheduleResult
        One per telescope, in the order given (empty for one with no window).
    metrics : JointMetrics
        Union, shares, own shares, covered more than once (of the map).
    bound : JointBound
        The certified bound on the union (J8).
    method : str
        ``alone`` (fewer than two telescopes observe), ``ascent`` or ``joint_model``.
    alone : tuple of ScheduleResult
        Each telescope's plan alone (the uncoordinated plans).
    names : tuple of str
        The telescopes' names.
    details : dict
        Diagnostics: the ascent's steps, the joint model's solve, the budget.
    """

    schedules: tuple[ScheduleResult, ...]
    metrics: JointMetrics
    bound: JointBound
    method: str
    alone: tuple[ScheduleResult, ...]
    names: tuple[str, ...]
    details: dict = field(default_factory=dict)


def _check_same_map(problems: Sequence[PlanningProblem]) -> None:
    """One map at one resolution for every telescope (ValueError otherwise)."""
    if not problems:
        raise ValueError("a joint plan needs at least one telescope's problem")
    first = problems[0]
    for p in problems[1:]:
        if p.footprints.nside != first.footprints.nside or p.prob.size != first.prob.size:
            raise ValueError("every telescope's problem must be at the same working resolution")
        if p.prob is not first.prob and not np.array_equal(p.prob, first.prob):
            raise ValueError("every telescope's problem must be on the same sky map")


def _joint_model_stage(problems, names, weight, start_plans, left: float, should_stop, details: dict
                       ) -> tuple[list[ScheduleResult] | None, float]:
    """(J6) The joint model, started from ``start_plans``, within ``left``; (its plans or None, budget spent)."""
    if left < MIN_JOINT_S:
        details["joint_model"] = "skipped: budget"
        return None, 0.0
    inst = joint_instance(problems, weight, names)
    if sum(p is not None for p in inst.parts) < 2 or inst.n_pairs > JOINT_MAX_PAIRS:
        details["joint_model"] = f"skipped: {inst.n_pairs} pairs"
        return None, 0.0
    # a telescope outside the model (a one-visit rule, no pair on its grid) keeps the ascent's plan, fixed
    fixed = [r if part is None else nothing() for r, part in zip(start_plans, inst.parts)]
    if any(f.observations for f in fixed):
        inst = reweighted(inst, masked(weight, problems, fixed, -1))
    model = build_joint_model(inst)
    x0 = joint_start(model, [r.observations for r in start_plans])
    cfg = problems[0].config
    clock = new_clock(cfg.deterministic)
    mark = clock.mark()
    res = solve_milp(model.milp, resolve_backend(cfg.milp_backend), left, cfg.mip_gap, cfg.threads, should_stop,
                     start=x0, clock=clock)
    spent = clock.since(mark)
    details["joint_model"] = {"size": model.milp.size(), "status": res.status, "objective": res.objective,
                              "bound": res.bound, "start_objective": None if x0 is None else float(model.milp.c @ x0)}
    if not res.has_solution:
        return None, spent
    plans = []
    for part, kept, (obs, dropped) in zip(inst.parts, fixed, decode_joint(model, res.x)):
        plans.append(kept if part is None else ScheduleResult(
            tuple(obs), f"joint:{res.backend}", res.status, res.gap, mip_bound=res.bound,
            dropped_by_slews=tuple(dropped)))
    return plans, spent


def joint_schedule(problems: Sequence[PlanningProblem], should_stop: StopCheck | None = None,
                   time_limit_s: float | None = None, names: Sequence[str] | None = None,
                   weight: np.ndarray | None = None, bound_time_limit_s: float | None = None,
                   greedy: bool = False) -> JointResult:
    """Plan several telescopes together on one map (J6), with the joint metrics and bound (J8).

    Parameters
    ----------
    problems : sequence of PlanningProblem
        One per telescope (each from :func:`~...prepare.prepare_problem` for
        its telescope), on the same sky map and working resolution.
    should_stop : callable, optional
        Polled by every solve; True ends the plan with what was found.
    time_limit_s : float, optional
        The whole plan's budget (s; work seconds when the telescopes'
        configs are ``deterministic``); default :data:`JOINT_BUDGET_FACTOR`
        times the sum of their ``time_limit_s``.  The bound comes on top.
    names : sequence of str, optional
        The telescopes' names (default: :func:`~.cells.telescope_names`, each problem's ``telescope``).
    weight : numpy.ndarray, optional
        (J5) Objective weight per pixel: the map's probability (default)
        with 0 where a telescope's executed record already covers.
    bound_time_limit_s : float, optional
        Budget (s) of the joint relaxation (J7); default the telescopes' largest.
    greedy : bool
        Every step greedy's plan and no joint model (``solver = "greedy"``: no MILP but the bound's).

    Returns
    -------
    JointResult
    """
    t0 = time.perf_counter()
    problems = tuple(problems)
    _check_same_map(problems)
    names = telescope_names(problems, names)
    w = problems[0].prob if weight is None else np.asarray(weight, float)
    if w.shape != problems[0].prob.shape or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weight must be one finite, non-negative number per pixel of the map")
    budget = JOINT_BUDGET_FACTOR * sum(p.config.time_limit_s for p in problems) if time_limit_s is None \
        else float(time_limit_s)
    alone, spent = [], 0.0
    for p in problems:
        result, cost = plan_alone(p, w, None, should_stop, greedy)
        alone.append(result)
        spent += cost
    details: dict = {"alone_spent_s": round(spent, 3)}
    results, method = list(alone), "alone"
    if sum(p.field_ids.size > 0 for p in problems) >= 2:
        left = budget - spent
        run = coordinate_ascent(problems, alone, w, left * (1.0 - JOINT_SHARE), should_stop, greedy)
        spent += run.spent
        results, method = run.results, "ascent"
        details["ascent"] = run.steps
        plans, cost = (None, 0.0) if greedy else _joint_model_stage(problems, names, w, results, budget - spent,
                                                                     should_stop, details)
        spent += cost
        model_union = None if plans is None else union_of(problems, plans, w)
        if isinstance(details.get("joint_model"), dict):
            details["joint_model"]["union"] = model_union  # its plan timed with the real overheads
        if model_union is not None and model_union > run.union + 1e-12:
            results, method = plans, "joint_model"
    results = [r if p.field_ids.size else nothing() for p, r in zip(problems, results)]
    bound = joint_upper_bound(problems, w, bound_time_limit_s, names)
    results = [dataclasses.replace(r, upper_bound=b) if p.field_ids.size else r  # (U5-U6) one visit too
               for p, r, b in zip(problems, results, bound.per_telescope)]
    fields = [{o.field_id for o in r.observations} for r in results]
    metrics = joint_metrics(problems, fields, problems[0].prob)
    details.update(budget_s=budget, spent_s=round(spent, 3), runtime_s=round(time.perf_counter() - t0, 3))
    return JointResult(tuple(results), metrics, bound, method, tuple(alone), names, details)
