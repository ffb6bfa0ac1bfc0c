"""A revision's parts for the other configured telescopes, planned around ZTF's revision (issue 53 items 2, 4).

:func:`plan_telescopes` is the one step the daemon takes for the telescopes
of ``[scheduler] telescopes`` after the first (ZTF, whose plan is the
revision itself): each is prepared on the map (its own problem: grid,
site, nights, limits, overheads, cadence) and planned **around** the plans
held fixed, ZTF's published revision and the parts already recorded for it
(:func:`~mushrooms.scheduler_core.joint_parts.plan_around`,
``docs/design/telescopes.md`` J9): the same probability is not observed
twice needlessly, and ZTF's revision is never changed.  :func:`plan_alone`
is the part each telescope would get alone (the uncoordinated baseline).

Never imports :mod:`mushrooms.daemon`.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

__all__ = ["plan_telescopes", "plan_alone", "prepare_telescopes"]

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


def prepare_telescopes(skymap: Any, runs: Sequence[tuple[Any, Any]], start: Any) -> dict[str, Any]:
    """Every telescope's problem on the map, by name; a telescope that failed gets its exception.

    Parameters
    ----------
    runs : sequence of (TelescopeDescription, PlanningConfig)
    start : astropy.time.Time
        Horizon start (ZTF's revision's).
    """
    from ..scheduler_core.prepare import prepare_problem

    out: dict[str, Any] = {}
    for telescope, config in runs:
        try:
            out[telescope.name] = prepare_problem(skymap, config, start, telescope=telescope)
        except Exception as exc:  # this telescope's failure only
            out[telescope.name] = exc
    return out


def plan_telescopes(skymap: Any, problems: Mapping[str, Any], todo: Sequence[str], held: Sequence[Any], key: str,
                    event: Any = None, should_stop: Callable[[], bool] | None = None) -> Mapping[str, PartPlan]:
    """The parts of ``todo`` planned around ``held``, by name; a telescope that failed gets its exception.

    One telescope's failure never loses the others' plans; it covers nothing for the next.

    Parameters
    ----------
    problems : mapping
        Name -> its problem, or the exception its preparation raised (:func:`prepare_telescopes`).
    todo : sequence of str
        The telescopes to plan, in the configured order.
    held : sequence of Held
        ZTF's revision and the parts recorded for it (:class:`~mushrooms.scheduler_core.joint_parts.Held`).
    key : str
        :func:`~mushrooms.scheduler_core.joint_parts.around_key` of ``held`` (it keys the parts' plan ids).
    """
    from ..scheduler_core.joint_parts import plan_around

    ready = [(name, problems[name]) for name in todo if not isinstance(problems[name], BaseException)]
    out: dict[str, PartPlan] = {name: problems[name] for name in todo if isinstance(problems[name], BaseException)}
    try:
        out.update(plan_around(skymap, held, ready, key, event, should_stop))
    except Exception as exc:  # the held plans themselves could not be read: every part fails, ZTF's revision stands
        out.update({name: exc for name, _ in ready})
    return out
