"""The one registry of scheduler names: name -> scheduler, and the list of names.

``PlanningConfig.solver`` validation (:mod:`.config`), :func:`~.planner.run_scheduler`,
the command line's ``--solver`` choices (:mod:`mushrooms.tool.common`) and
the benchmark's rows (:mod:`mushrooms.evaluation.bench`, which adds its
external baselines) all read it.

This module imports nothing heavy: each scheduler is imported the first time
its name is looked up (the MILP stack only when a MILP scheduler is used).

=========  ==================================================================
``greedy``  the greedy scheduler (:func:`~.schedulers.greedy.greedy_schedule`)
``slots``   greedy, then the slot-assignment MILP portfolio started from it
            (:func:`~.schedulers.portfolio.slots_from_greedy`), with the bound
``blocks``  the paper's block MILP (:func:`~.schedulers.block_schedule.milp_schedule`),
            with the bound
``hybrid``  ``best_of(greedy, slots, blocks)`` (:data:`~.schedulers.portfolio.hybrid`),
            with the bound
``milp``    the old name of ``blocks`` (kept for old configs)
=========  ==================================================================

"With the bound": the result carries the certified coverage upper bound
(:func:`~.schedulers.portfolio.with_upper_bound`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from .problem import Scheduler

__all__ = ["SOLVER_NAMES", "get_scheduler", "unknown_solver_message"]


def _greedy() -> "Scheduler":
    from .schedulers.greedy import greedy_schedule

    return greedy_schedule


def _slots() -> "Scheduler":
    from .schedulers.portfolio import slots_from_greedy, with_upper_bound

    return with_upper_bound(slots_from_greedy)


def _blocks() -> "Scheduler":
    from .schedulers.portfolio import blocks, with_upper_bound

    return with_upper_bound(blocks)


def _hybrid() -> "Scheduler":
    from .schedulers.portfolio import hybrid, with_upper_bound

    return with_upper_bound(hybrid)


#: name -> the function building its scheduler (called at the first look-up), in the order of the names.
_BUILDERS: dict[str, Callable[[], "Scheduler"]] = {
    "greedy": _greedy, "slots": _slots, "blocks": _blocks, "hybrid": _hybrid, "milp": _blocks,
}

#: Scheduler names; ``milp`` is the old name of ``blocks`` (kept for old configs).
SOLVER_NAMES: tuple[str, ...] = tuple(_BUILDERS)

_built: dict[str, "Scheduler"] = {}


def unknown_solver_message(name: object) -> str:
    """``unknown solver 'x'; choose one of greedy, slots, ...``."""
    return f"unknown solver {name!r}; choose one of {', '.join(SOLVER_NAMES)}"


def get_scheduler(name: str) -> "Scheduler":
    """The scheduler of a name (:data:`SOLVER_NAMES`).

    Raises
    ------
    InputError
        An unknown name (:func:`unknown_solver_message`).
    """
    if name not in _BUILDERS:
        from .errors import InputError

        raise InputError(unknown_solver_message(name))
    if name not in _built:
        _built[name] = _BUILDERS[name]()
    return _built[name]
