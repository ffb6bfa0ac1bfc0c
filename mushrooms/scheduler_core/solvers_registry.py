"""The one registry of scheduler names: the list of names, and name -> scheduler.

``PlanningConfig.solver`` validation (:mod:`.config`), :func:`~.planner.run_scheduler`,
the command line's ``--solver`` choices (:mod:`mushrooms.tool.common`) and
the benchmark's rows (:mod:`mushrooms.evaluation.bench`, which adds its
external baselines) all read it.

The module is a leaf (it imports nothing of the package, so the config can
validate against it): the schedulers register themselves
(:mod:`.schedulers.portfolio.portfolio` registers every built-in one, and
:mod:`.planner` imports it), only under a name of :data:`SOLVER_NAMES`.

============  ===============================================================
``greedy``    the greedy scheduler (:func:`~.schedulers.greedy.schedule.greedy_schedule`)
``slots``     greedy, then the slot-assignment MILP portfolio started from it
              (:func:`~.schedulers.portfolio.portfolio.slots_from_greedy`), with the bound
``blocks``    the paper's block MILP (:func:`~.schedulers.portfolio.portfolio.blocks`), with the bound
``hybrid``    ``best_of(greedy, slots, lns, blocks)`` (:data:`~.schedulers.portfolio.portfolio.hybrid`),
              with the bound
``milp``      the old name of ``blocks`` (kept for old configs)
============  ===============================================================

"With the bound": the result carries the certified coverage upper bound
(:func:`~.schedulers.portfolio.portfolio.with_upper_bound`).
"""

from __future__ import annotations

from typing import Any, Callable

__all__ = ["SOLVER_NAMES", "register", "get_scheduler", "registered", "unknown_solver_message"]

#: Scheduler names; ``milp`` is the old name of ``blocks`` (kept for old configs).
SOLVER_NAMES: tuple[str, ...] = ("greedy", "slots", "blocks", "hybrid", "milp")

#: name -> scheduler (``scheduler(problem, should_stop) -> ScheduleResult``, :data:`~.problem.Scheduler`).
_SCHEDULERS: dict[str, Callable[..., Any]] = {}


def unknown_solver_message(name: object) -> str:
    """``unknown solver 'x'; choose one of greedy, slots, ...``."""
    return f"unknown solver {name!r}; choose one of {', '.join(SOLVER_NAMES)}"


def register(name: str, scheduler: Callable[..., Any]) -> None:
    """Make ``scheduler`` the scheduler of ``name`` (one of :data:`SOLVER_NAMES`)."""
    if name not in SOLVER_NAMES:
        raise ValueError(f"{name!r} is not a scheduler name ({', '.join(SOLVER_NAMES)})")
    _SCHEDULERS[name] = scheduler


def registered() -> dict[str, Callable[..., Any]]:
    """A copy of the table name -> scheduler."""
    return dict(_SCHEDULERS)


def get_scheduler(name: str) -> Callable[..., Any]:
    """The scheduler of a name (:data:`SOLVER_NAMES`).

    Raises
    ------
    InputError
        An unknown name (:func:`unknown_solver_message`).
    LookupError
        A name no scheduler was registered for (the built-in ones are
        registered when :mod:`.schedulers.portfolio.portfolio` is imported, as
        :mod:`.planner` does).
    """
    if name not in SOLVER_NAMES:
        from .errors import InputError  # errors is a leaf too

        raise InputError(unknown_solver_message(name))
    try:
        return _SCHEDULERS[name]
    except KeyError:
        raise LookupError(f"no scheduler registered for {name!r} "
                          "(import mushrooms.scheduler_core.schedulers.portfolio.portfolio)") from None
