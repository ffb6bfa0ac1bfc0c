"""Anytime planning: a checked fast plan at once, a better one if time allows.

The fast scheduler (greedy) answers within a second; the configured one
(MILP or hybrid) may need tens of seconds.  :func:`anytime_plans` yields the
fast plan first and then the optimised one, each checked, so a caller can
publish the first while the second is being found; :func:`is_better` is the
rule by which a later plan replaces an earlier one.  Plan documents carry
``revision`` (1, 2, ...) and ``final`` (no further revision of this sky map
will follow) via :func:`revision_document`.
"""

from __future__ import annotations

import time
from typing import Any, Callable, Iterator

from .plan.checker import check_plan
from .errors import PlanCheckError
from .plan.document import EventInfo, Plan
from .planner import build_plan, run_scheduler
from .problem import PlanningProblem, ScheduleResult, StopCheck
from .sky.skymap import SkyMap

__all__ = ["FIRST_SOLVER", "checked_plan", "anytime_plans", "is_better", "revision_document"]

#: The scheduler of every first plan (fast, never needs a time limit).
FIRST_SOLVER = "greedy"

Scheduler = Callable[[PlanningProblem, str, "StopCheck | None"], ScheduleResult]


def checked_plan(problem: PlanningProblem, result: ScheduleResult, skymap: SkyMap, solver: str,
                 event: EventInfo | None = None, supersedes: str | None = None,
                 runtime_s: float | None = None) -> Plan:
    """:func:`~.planner.build_plan` followed by the independent checker.

    Raises
    ------
    PlanCheckError
        The plan breaks a rule (a scheduler bug; never publish it).
    """
    plan = build_plan(problem, result, skymap, solver, event=event, supersedes=supersedes, runtime_s=runtime_s)
    report = check_plan(plan, skymap, problem.config)
    if not report.ok:
        raise PlanCheckError(list(report.problems))
    return plan


def is_better(candidate: Plan, incumbent: Plan, min_gain: float) -> bool:
    """True when ``candidate`` covers more than ``incumbent`` by at least ``min_gain``.

    Parameters
    ----------
    candidate, incumbent : Plan
    min_gain : float
        Least absolute gain in probability coverage (0 to 1); the gain must
        also be positive, so equal plans never replace each other.
    """
    gain = float(candidate.metrics.coverage) - float(incumbent.metrics.coverage)
    return gain > 0 and gain >= min_gain


def anytime_plans(problem: PlanningProblem, skymap: SkyMap, solver: str, event: EventInfo | None = None,
                  supersedes: str | None = None, should_stop: StopCheck | None = None,
                  scheduler: Scheduler = run_scheduler) -> Iterator[Plan]:
    """Yield the checked fast plan, then (unless ``solver`` is the fast one) the optimised one.

    The fast plan always runs to the end (it takes well under a second);
    ``should_stop`` is passed to the optimising scheduler, which then
    returns its best plan so far.  The optimised plan's ``supersedes`` is
    the fast plan's id; whether it is worth publishing is the caller's
    choice (:func:`is_better`).

    Parameters
    ----------
    problem : PlanningProblem
    skymap : SkyMap
    solver : str
        The configured scheduler (``config.solver``).
    event : EventInfo, optional
    supersedes : str, optional
        plan_id the fast plan replaces (an earlier sky map's plan).
    should_stop : callable, optional
    scheduler : callable, optional
        ``run_scheduler``-compatible function.
    """
    t0 = time.perf_counter()
    first = checked_plan(problem, scheduler(problem, FIRST_SOLVER, None), skymap, FIRST_SOLVER, event=event,
                         supersedes=supersedes, runtime_s=time.perf_counter() - t0)
    yield first
    if solver == FIRST_SOLVER:
        return
    t1 = time.perf_counter()
    yield checked_plan(problem, scheduler(problem, solver, should_stop), skymap, solver, event=event,
                       supersedes=first.plan_id, runtime_s=time.perf_counter() - t1)


def revision_document(plan: Plan, revision: int, final: bool) -> dict[str, Any]:
    """The plan document with ``revision`` (1, 2, ...) and ``final`` added."""
    doc = plan.to_document()
    doc["revision"] = int(revision)
    doc["final"] = bool(final)
    return doc
