"""Anytime planning: a checked fast plan at once, a better one if time allows.

The fast scheduler (greedy) answers within a second; the configured one
(MILP or hybrid) may need tens of seconds.  :func:`anytime_plans` yields the
fast plan first and then the optimised one, each checked, so a caller can
publish the first while the second is being found; :func:`is_better` is the
rule by which a later plan replaces an earlier one, and :func:`supersession`
the whole decision after the optimisation (revision 1 stands or revision 2
replaces it, and why), the one the daemon and the bench's ``service`` row
both take.  The two stages are also
:func:`first_plan` and :func:`optimised_plan`, for a caller that publishes
between them and runs the second later (the daemon's
:class:`~mushrooms.daemon.planning.revisions.JobPlanner`, which queues optimisations
behind newer first plans): ``mushrooms plan --deadline`` and the daemon run
the same flow.  Plan documents carry ``revision`` (1, 2, ...) and ``final``
(no further revision of this sky map will follow) via
:func:`~.plan.messages.revision_document` (re-exported here).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Iterator, Literal

from .plan.checker import check_plan
from .errors import PlanCheckError
from .plan.document import EventInfo, Plan
from .plan.messages import revision_document
from .plan.observability import not_observable
from .planner import build_plan, optimise, run_scheduler
from .preference import is_preferred
from .problem import PlanningProblem, ScheduleResult, StopCheck
from .sky.skymap import SkyMap
from .config import PlanningConfig

__all__ = ["FIRST_SOLVER", "checked_plan", "first_plan", "optimised_plan", "anytime_plans", "is_better",
           "Supersession", "supersession", "revision_document"]

#: The scheduler of every first plan (fast, never needs a time limit).
FIRST_SOLVER = "greedy"

#: ``run_scheduler``-compatible: ``(problem, solver name, should_stop) -> ScheduleResult``.
SchedulerByName = Callable[[PlanningProblem, str, "StopCheck | None"], ScheduleResult]


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


def is_better(candidate: Plan, incumbent: Plan, min_gain: float, objective: str = "coverage",
              max_coverage_loss: float = 0.0) -> bool:
    """True when ``candidate`` is better than ``incumbent`` by the rule R1-R3 (:mod:`.preference`).

    ``coverage`` (or no expected detections on either plan: no distance
    layers): the candidate covers more by at least ``min_gain``.
    ``detection``: the candidate has more expected detections by at least
    ``min_gain`` (the probability of detecting the kilonova, 0 to 1, the
    same units as coverage) and covers at least ``(1 - max_coverage_loss)``
    of the incumbent's coverage (the floor X6); when the expected
    detections differ by less than ``min_gain`` (a tie, e.g. both ~0: a
    source too far for the light curve), coverage decides as for
    ``coverage``.

    Parameters
    ----------
    candidate, incumbent : Plan
    min_gain : float
        Least absolute gain (0 to 1); the gain must also be positive, so
        equal plans never replace each other.
    objective : str
        ``coverage`` or ``detection`` (``config.objective``).
    max_coverage_loss : float
        ε of the coverage floor (``config.detection_max_coverage_loss``), relative.
    """
    c_old = float(incumbent.metrics.coverage)
    return is_preferred(float(candidate.metrics.coverage), candidate.metrics.expected_detections, c_old,
                        incumbent.metrics.expected_detections, min_gain, objective,
                        coverage_floor=(1.0 - max_coverage_loss) * c_old)


@dataclass(frozen=True)
class Supersession:
    """Which plan of a sky map is published once the optimisation is over, and why.

    Attributes
    ----------
    revision : int
        1 (the first plan stands) or 2 (the optimised plan replaces it).
    plan : Plan
        The plan published: the first or the optimised one.
    reason : str
        ``"better"`` (revision 2); for revision 1: ``"no_plan"`` (the
        optimisation gave none: it failed, or its plan failed the checker;
        the caller knows which), ``"below_min_coverage"`` (the optimised plan
        would be the ``not_observable`` answer), ``"not_better"`` (the same
        plan, or not better by the margin, :func:`is_better`).
    """

    revision: Literal[1, 2]
    plan: Plan
    reason: Literal["better", "no_plan", "below_min_coverage", "not_better"]


def supersession(first: Plan, optimised: Plan | None, skymap: SkyMap, config: PlanningConfig,
                 min_gain: float) -> Supersession:
    """Decide whether the optimised plan replaces the published first plan (revision 2) or the first stands.

    The optimised plan replaces the first when there is one, it covers at
    least ``config.min_coverage`` (else it would be the ``not_observable``
    answer, :func:`~.plan.observability.not_observable`), it is another plan
    (another ``plan_id``) and it is better by ``min_gain`` under
    ``config.objective`` (:func:`is_better`, rule R1-R3).

    Parameters
    ----------
    first : Plan
        Revision 1, the first plan (:func:`first_plan`), published.
    optimised : Plan or None
        The checked plan of ``config.solver`` (:func:`optimised_plan`); None
        when the optimisation gave none.
    skymap : SkyMap
        The sky map both plans were made for.
    config : PlanningConfig
        ``objective``, ``detection_max_coverage_loss`` (relative) and
        ``min_coverage`` (0 to 1).
    min_gain : float
        What revision 2 must gain (``[daemon] supersede_min_gain``; coverage
        or expected detections, 0 to 1).

    Returns
    -------
    Supersession
    """
    if optimised is None:
        return Supersession(1, first, "no_plan")
    if not_observable(optimised, skymap, config) is not None:
        return Supersession(1, first, "below_min_coverage")
    if optimised.plan_id != first.plan_id and is_better(optimised, first, min_gain, config.objective,
                                                        config.detection_max_coverage_loss):
        return Supersession(2, optimised, "better")
    return Supersession(1, first, "not_better")


def first_plan(problem: PlanningProblem, skymap: SkyMap, event: EventInfo | None = None,
               supersedes: str | None = None, should_stop: StopCheck | None = None,
               scheduler: Scheduler = run_scheduler, started: float | None = None) -> Plan:
    """The checked plan of the fast scheduler (:data:`FIRST_SOLVER`): the anytime flow's first answer.

    Parameters
    ----------
    problem : PlanningProblem
    skymap : SkyMap
    event : EventInfo, optional
    supersedes : str, optional
        plan_id the plan replaces (an earlier sky map's plan).
    should_stop : callable, optional
        Passed to the scheduler (the daemon's: the job was superseded).
    scheduler : callable, optional
        ``run_scheduler``-compatible function.
    started : float, optional
        ``time.perf_counter()`` the plan's ``runtime_s`` counts from
        (the daemon: the job's start, sky map reading included); default now.

    Raises
    ------
    PlanCheckError
        The plan breaks a rule.
    """
    t0 = time.perf_counter() if started is None else started
    result = scheduler(problem, FIRST_SOLVER, should_stop)
    return checked_plan(problem, result, skymap, FIRST_SOLVER, event=event, supersedes=supersedes,
                        runtime_s=time.perf_counter() - t0)


def optimised_plan(problem: PlanningProblem, skymap: SkyMap, solver: str, incumbent: Plan,
                   event: EventInfo | None = None, should_stop: StopCheck | None = None,
                   scheduler: Scheduler = run_scheduler,
                   interrupted: Callable[[], bool] | None = None) -> Plan | None:
    """The checked plan of ``solver`` (:func:`~.planner.optimise`) that would supersede ``incumbent``.

    Whether it is worth publishing is :func:`is_better`'s call.

    Parameters
    ----------
    problem : PlanningProblem
    skymap : SkyMap
    solver : str
        The configured scheduler (``config.solver``).
    incumbent : Plan
        The first plan: the result's ``supersedes``.
    event : EventInfo, optional
    should_stop : callable, optional
        Passed to the optimisation, which then returns its best plan so far.
    scheduler : callable, optional
        ``run_scheduler``-compatible function.
    interrupted : callable, optional
        Asked once the search returns: True (the daemon's job was superseded
        meanwhile) skips the plan check and returns None.

    Raises
    ------
    PlanCheckError
        The plan breaks a rule.
    """
    t1 = time.perf_counter()
    result = optimise(problem, skymap, solver, should_stop, scheduler=scheduler)
    if interrupted is not None and interrupted():
        return None
    return checked_plan(problem, result, skymap, solver, event=event, supersedes=incumbent.plan_id,
                        runtime_s=time.perf_counter() - t1)


def anytime_plans(problem: PlanningProblem, skymap: SkyMap, solver: str, event: EventInfo | None = None,
                  supersedes: str | None = None, should_stop: StopCheck | None = None,
                  scheduler: SchedulerByName = run_scheduler) -> Iterator[Plan]:
    """Yield the checked fast plan, then (unless ``solver`` is the fast one) the optimised one.

    The fast plan always runs to the end (it takes well under a second);
    ``should_stop`` is passed to the optimisation (:func:`~.planner.optimise`:
    the scheduler, then the detection stage when ``config.objective`` is
    ``detection``), which then returns its best plan so far.  The optimised plan's ``supersedes`` is
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
    first = first_plan(problem, skymap, event=event, supersedes=supersedes, scheduler=scheduler)
    yield first
    if solver == FIRST_SOLVER:
        return
    better = optimised_plan(problem, skymap, solver, first, event=event, should_stop=should_stop,
                            scheduler=scheduler)
    assert better is not None  # no ``interrupted``
    yield better
