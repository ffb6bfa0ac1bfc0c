"""A coordinated plan of several telescopes as one checked :class:`~.plan.document.Plan` per telescope.

:func:`make_joint_plans` runs :func:`~.schedulers.joint.schedule.joint_schedule`
(``docs/design/telescopes.md``, J1-J8) on one problem per telescope and
turns each telescope's schedule into a plan with :func:`~.planner.build_plan`
(the least-gain rule, airmasses, depths, the telescope's own bound), each
checked by the single-telescope plan checker against its own configuration
(windows, overheads, filters, cadence): a part the checker refuses is never
published (:class:`~.errors.PlanCheckError`).  The joint metrics and bound
stay on the :class:`~.schedulers.joint.schedule.JointResult`;
:func:`joint_document` writes the whole as one ``joint_plan`` document
(``docs/design/plan-format.md``): every telescope's plan document as it
is alone, the observations of all of them in time order each naming its
telescope, the joint metrics and the bound.
"""

from __future__ import annotations

import dataclasses
from typing import Sequence

from .errors import PlanCheckError
from .plan.checker import check_plan
from .plan.document import EventInfo, Plan, make_plan_id
from .planner import build_plan
from .problem import PlanningProblem, StopCheck
from .schedulers.joint.bound import JointBound
from .schedulers.joint.cells import JointMetrics, joint_metrics
from .schedulers.joint.schedule import JointResult, joint_schedule
from .sky.skymap import SkyMap

__all__ = ["make_joint_plans", "joint_document", "joint_metrics_document", "JOINT_SOLVER"]

#: The solver name a joint plan's parts record (their plan ids depend on it).
JOINT_SOLVER = "joint"


def make_joint_plans(skymap: SkyMap, problems: Sequence[PlanningProblem], names: Sequence[str] | None = None,
                     event: EventInfo | None = None, should_stop: StopCheck | None = None,
                     time_limit_s: float | None = None, greedy: bool = False) -> tuple[list[Plan], JointResult]:
    """Plan several telescopes together and build one checked plan per telescope.

    Parameters
    ----------
    skymap : SkyMap
        The map every problem was prepared on.
    problems : sequence of PlanningProblem
        One per telescope (:func:`~.prepare.prepare_problem` for each).
    names : sequence of str, optional
        Telescope names (default: each problem's ``telescope``, ``scheduler_core/schedulers/joint/cells.py``).
    event : EventInfo, optional
        The alert answered.
    should_stop : callable, optional
        Polled by every solve.
    time_limit_s : float, optional
        The joint budget (default: :func:`~.schedulers.joint.schedule.joint_schedule`'s).
    greedy : bool
        Greedy's steps only (``solver = "greedy"``).

    Returns
    -------
    plans : list of Plan
        One per telescope, in order (a telescope with no window: a plan with
        no observation).
    result : JointResult
        The schedules, the bound, and the joint metrics of the plans as
        published (each part after its telescope's least-gain rule).

    Raises
    ------
    PlanCheckError
        A telescope's part failed the plan checker (named in the message).
    """
    result = joint_schedule(problems, should_stop, time_limit_s=time_limit_s, names=names, greedy=greedy)
    plans = []
    for name, problem, part in zip(result.names, problems, result.schedules):
        plan = build_plan(problem, part, skymap, JOINT_SOLVER + ("-greedy" if greedy else ""), event=event)
        report = check_plan(plan, skymap, problem.config)
        if not report.ok:
            raise PlanCheckError([f"{name}: {line}" for line in report.problems])
        plans.append(plan)
    # the metrics of the plans as published: each part after its telescope's least-gain rule (build_plan)
    fields = [{o.field_id for o in plan.observations} for plan in plans]
    return plans, dataclasses.replace(result, metrics=joint_metrics(problems, fields, problems[0].prob))


def joint_document(plans: Sequence[Plan], result: JointResult) -> dict:
    """The ``joint_plan`` document of a coordinated plan (``docs/design/plan-format.md``).

    Parameters
    ----------
    plans : sequence of Plan
        One per telescope (:func:`make_joint_plans`), in ``result.names`` order.
    result : JointResult
        Their joint schedule: metrics and bound.

    Returns
    -------
    dict
        ``type`` ``joint_plan``; ``plan_id`` from the parts' ids; ``telescopes``;
        ``observations``: every part's, in time order, each with its
        ``telescope``; ``metrics``: the union, shares, own shares, covered
        more than once, the bound (J8) and its three terms; ``plans``: each
        telescope's own plan document, unchanged.
    """
    return joint_metrics_document(list(result.names), [plan.to_document() for plan in plans], result.metrics,
                                  result.bound, result.method)


def joint_metrics_document(names: Sequence[str], parts: Sequence[dict], metrics: JointMetrics | None,
                           bound: JointBound | None, method: str) -> dict:
    """The ``joint_plan`` document of plan documents ``parts`` (one per name), their joint metrics and bound.

    ``metrics``/``bound`` None (no telescope has a plan): a union of 0 under a bound of 0.
    """
    names = list(names)
    observations = sorted(({**o, "telescope": name} for name, part in zip(names, parts) for o in part["observations"]),
                          key=lambda o: (o["start"], names.index(o["telescope"])))
    finite = (lambda v: round(float(v), 6) if v != float("inf") else None)
    out = dict(metrics.as_dict(names) if metrics is not None else {"union": 0.0, "more_than_once": 0.0, "share": {},
                                                                    "own": {}})
    if bound is not None:
        out.update(upper_bound=round(bound.value, 6), upper_bound_method=bound.method,
                   upper_bound_terms={"joint": finite(bound.joint), "sum_of_telescopes": finite(bound.sum_of_telescopes),
                                      "total": finite(bound.total)}, upper_bound_status=bound.status)
    else:
        out.update(upper_bound=0.0, upper_bound_method="empty", upper_bound_terms={}, upper_bound_status="empty")
    out.update(method=method, n_exposures={name: len(part["observations"]) for name, part in zip(names, parts)})
    return {"type": "joint_plan", "plan_id": make_plan_id("joint", [part["plan_id"] for part in parts]),
            "created": parts[0].get("created") if parts else None,
            "event": parts[0]["event"] if parts else None, "telescopes": names,
            "start": min(part["start"] for part in parts) if parts else None,
            "end": max(part["end"] for part in parts) if parts else None,
            "observations": observations, "metrics": out, "plans": list(parts)}
