"""A coordinated plan of several telescopes as one checked :class:`~.plan.document.Plan` per telescope.

:func:`make_joint_plans` runs :func:`~.schedulers.joint.schedule.joint_schedule`
(``docs/design/telescopes.md``, J1-J8) on one problem per telescope and
turns each telescope's schedule into a plan with :func:`~.planner.build_plan`
(the least-gain rule, airmasses, depths, the telescope's own bound), each
checked by the single-telescope plan checker against its own configuration
(windows, overheads, filters, cadence): a part the checker refuses is never
published (:class:`~.errors.PlanCheckError`).  The joint metrics and bound
stay on the :class:`~.schedulers.joint.schedule.JointResult`.
"""

from __future__ import annotations

from typing import Sequence

from .errors import PlanCheckError
from .plan.checker import check_plan
from .plan.document import EventInfo, Plan
from .planner import build_plan
from .problem import PlanningProblem, StopCheck
from .schedulers.joint.schedule import JointResult, joint_schedule
from .sky.skymap import SkyMap

__all__ = ["make_joint_plans", "JOINT_SOLVER"]

#: The solver name a joint plan's parts record (their plan ids depend on it).
JOINT_SOLVER = "joint"


def make_joint_plans(skymap: SkyMap, problems: Sequence[PlanningProblem], names: Sequence[str] | None = None,
                     event: EventInfo | None = None, should_stop: StopCheck | None = None,
                     time_limit_s: float | None = None) -> tuple[list[Plan], JointResult]:
    """Plan several telescopes together and build one checked plan per telescope.

    Parameters
    ----------
    skymap : SkyMap
        The map every problem was prepared on.
    problems : sequence of PlanningProblem
        One per telescope (:func:`~.prepare.prepare_problem` for each).
    names : sequence of str, optional
        Telescope names (default ``t0``, ``t1``, ...).
    event : EventInfo, optional
        The alert answered.
    should_stop : callable, optional
        Polled by every solve.
    time_limit_s : float, optional
        The joint budget (default: :func:`~.schedulers.joint.schedule.joint_schedule`'s).

    Returns
    -------
    plans : list of Plan
        One per telescope, in order (a telescope with no window: a plan with
        no observation).
    result : JointResult
        The schedules, the joint metrics and the bound.

    Raises
    ------
    PlanCheckError
        A telescope's part failed the plan checker (named in the message).
    """
    result = joint_schedule(problems, should_stop, time_limit_s=time_limit_s, names=names)
    plans = []
    for name, problem, part in zip(result.names, problems, result.schedules):
        plan = build_plan(problem, part, skymap, JOINT_SOLVER, event=event)
        report = check_plan(plan, skymap, problem.config)
        if not report.ok:
            raise PlanCheckError([f"{name}: {line}" for line in report.problems])
        plans.append(plan)
    return plans, result
