"""A revision's plans for the other configured telescopes (issue 53, phase 4: through the service).

:func:`plan_telescopes` is the one step the daemon takes per revision for every
telescope of ``[scheduler] telescopes`` after the first (ZTF, whose plan is the
revision itself).  Today each telescope is planned **alone** (phase 2's path:
its own problem, the fast scheduler, the checker, the ``not_observable`` rule);
the joint coordinated plan (``schedulers/joint/``, ``docs/design/telescopes.md``
section 5) replaces the body of :func:`plan_telescopes` with one call.

Never imports :mod:`mushrooms.daemon`.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

__all__ = ["plan_telescopes", "plan_alone"]

#: What a telescope's planning gives: its checked plan, its ``not_observable`` answer, or the exception.
PartPlan = Any


def plan_alone(skymap: Any, telescope: Any, config: Any, start: Any, event: Any = None,
               should_stop: Callable[[], bool] | None = None) -> PartPlan:
    """One telescope's plan alone: the fast scheduler's checked plan, or its ``not_observable`` answer.

    Parameters
    ----------
    skymap : SkyMap
    telescope : TelescopeDescription
    config : PlanningConfig
        Made for ``telescope`` (:meth:`PlanningConfig.for_telescope`).
    start : astropy.time.Time
        Horizon start (the ZTF revision's).
    event : EventInfo, optional
    should_stop : callable, optional
    """
    from ..scheduler_core import not_observable
    from ..scheduler_core.anytime import first_plan
    from ..scheduler_core.prepare import prepare_problem

    problem = prepare_problem(skymap, config, start, telescope=telescope)
    plan = first_plan(problem, skymap, event=event, should_stop=should_stop)
    answer = not_observable(plan, skymap, config)
    return plan if answer is None else answer


def plan_telescopes(skymap: Any, runs: Sequence[tuple[Any, Any]], start: Any, event: Any = None,
                    should_stop: Callable[[], bool] | None = None) -> Mapping[str, PartPlan]:
    """Every telescope's plan of one revision, by name; a telescope that failed gets its exception.

    One telescope's failure never loses the others' plans.  To plan them
    jointly, return the joint plan's per-telescope parts here instead (the
    daemon's only call of it: :mod:`mushrooms.daemon.planning.parts`).

    Parameters
    ----------
    runs : sequence of (TelescopeDescription, PlanningConfig)
    """
    out: dict[str, PartPlan] = {}
    for telescope, config in runs:
        try:
            out[telescope.name] = plan_alone(skymap, telescope, config, start, event, should_stop)
        except Exception as exc:  # this telescope's failure only
            out[telescope.name] = exc
    return out
