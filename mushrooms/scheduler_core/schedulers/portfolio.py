"""Schedulers made of schedulers: the slot scheduler seeded by greedy, the hybrid portfolio, the bound.

A scheduler (:data:`~..problem.Scheduler`) is ``scheduler(problem,
should_stop) -> ScheduleResult``.  A :class:`Stage` is one step of a
composition: it also sees the results of the stages before it and the
budget (s) left of ``config.time_limit_s``.  :func:`best_of` runs stages in
turn and keeps the plan that, as it will be published (after the
least-gain rule), covers the most probability, the earliest stage winning
a tie; :func:`with_upper_bound` attaches the certified coverage bound
(:mod:`.bound`) to a scheduler's result.  The named schedulers of
:mod:`..solvers_registry` are built from these, and this module registers them there
(``greedy``, ``slots``, ``blocks`` / ``milp``, ``hybrid``).

The MILP modules are imported by the stages when they run (and looked up
there, so a test can replace ``slot_schedule.slot_schedule``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Callable, Mapping

from ..problem import PlanningProblem, PortfolioEntry, ScheduleResult, Scheduler, StopCheck
from ..solvers_registry import register
from .gain import published_coverage
from .greedy import greedy_schedule

__all__ = ["Stage", "StageRun", "Portfolio", "best_of", "with_upper_bound", "greedy_stage", "slots_stage",
           "blocks_stage", "slots_from_greedy", "blocks", "hybrid", "MIN_BLOCKS_S"]

#: The hybrid runs the block MILP only when at least this much (s) of its budget is left.
MIN_BLOCKS_S = 3.0

#: ``run(problem, should_stop, earlier, left_s)``: ``earlier`` maps the stages already run to their
#: results (in order), ``left_s`` is what is left (s) of ``config.time_limit_s``, possibly negative.
StageRun = Callable[[PlanningProblem, "StopCheck | None", Mapping[str, ScheduleResult], float], ScheduleResult]


@dataclass(frozen=True)
class Stage:
    """One step of a composed scheduler.

    Attributes
    ----------
    name : str
        Its name in the portfolio (``greedy``, ``slots``, ``blocks``).
    run : StageRun
        The step.
    min_left_s : float or None
        None: the stage always runs.  Else it runs only when at least this
        much of the budget is left and ``should_stop`` (polled once, before
        it) does not say stop.
    """

    name: str
    run: StageRun
    min_left_s: float | None = None


def greedy_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                 earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The greedy scheduler (no budget: it takes well under a second)."""
    return greedy_schedule(problem, should_stop)


def slots_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The slot portfolio with what is left, started from greedy's plan."""
    from .slot_schedule import slot_schedule

    return slot_schedule(problem, should_stop, start=earlier.get("greedy"), time_limit_s=max(left_s, 0.0))


def blocks_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                 earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The block MILP with what is left.

    It is a coverage scheduler: its budget is what is left, whatever the
    objective (a detection config would refuse a budget shorter than its
    detection stage's share).
    """
    from .block_schedule import milp_schedule

    timed = dataclasses.replace(problem, config=dataclasses.replace(
        problem.config, time_limit_s=left_s, objective="coverage"))
    return milp_schedule(timed, should_stop)


@dataclass(frozen=True)
class Portfolio:
    """Run stages in turn; keep the plan covering the most as published (a tie: the earlier stage).

    Calling it is a :data:`~..problem.Scheduler`.  The result is the
    winner's, with ``solver`` ``<label>(<winner's solver>)``, the whole
    wall time, ``portfolio`` (each candidate's solver, status, gap and
    published coverage) and ``portfolio_choice`` (the winning stage).
    """

    label: str
    stages: tuple[Stage, ...]

    def __call__(self, problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
        t0 = time.perf_counter()
        budget = problem.config.time_limit_s
        ran: dict[str, ScheduleResult] = {}
        for stage in self.stages:
            left = budget - (time.perf_counter() - t0)
            if stage.min_left_s is not None:
                stopped = should_stop is not None and should_stop()
                if left < stage.min_left_s or stopped:
                    continue
            ran[stage.name] = stage.run(problem, should_stop, ran, left)
        names = list(ran)
        covs = {name: published_coverage(problem, r) for name, r in ran.items()}
        name = max(names, key=lambda n: (covs[n], -names.index(n)))
        best = ran[name]
        entries = tuple(PortfolioEntry(n, r.solver, r.status, r.mip_gap, covs[n]) for n, r in ran.items())
        return dataclasses.replace(best, solver=f"{self.label}({best.solver})", runtime_s=time.perf_counter() - t0,
                                   portfolio=entries, portfolio_choice=name)


def best_of(label: str, *stages: Stage) -> Portfolio:
    """The :class:`Portfolio` of ``stages``, its results' solver named ``label(...)``."""
    return Portfolio(label, tuple(stages))


def slots_from_greedy(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
    """Greedy, then the slot portfolio started from it with the budget left.

    When the slot portfolio ends without a plan and greedy has one, the
    greedy plan is returned under the slot scheduler's name, status
    ``<status>_greedy_fallback``.
    """
    t0 = time.perf_counter()
    greedy = greedy_stage(problem, should_stop, {}, problem.config.time_limit_s)
    left = problem.config.time_limit_s - (time.perf_counter() - t0)
    slots = slots_stage(problem, should_stop, {"greedy": greedy}, left)
    if not slots.observations and greedy.observations:
        slots = dataclasses.replace(slots, status=f"{slots.status}_greedy_fallback",
                                    observations=greedy.observations,
                                    details=dict(slots.details, greedy_details=greedy.details))
    return dataclasses.replace(slots, runtime_s=time.perf_counter() - t0)


def blocks(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
    """The block MILP with the whole budget."""
    from .block_schedule import milp_schedule

    return milp_schedule(problem, should_stop)


def with_upper_bound(scheduler: Scheduler) -> Scheduler:
    """``scheduler`` whose result carries the certified coverage upper bound of the problem (:mod:`.bound`)."""

    def bounded(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
        from .bound import coverage_upper_bound

        result = scheduler(problem, should_stop)
        return dataclasses.replace(result, upper_bound=coverage_upper_bound(problem))

    bounded.__name__ = bounded.__qualname__ = f"with_upper_bound({getattr(scheduler, '__name__', scheduler)!s})"
    bounded.__doc__ = scheduler.__doc__
    return bounded


#: The hybrid: greedy, the slot portfolio from it, then (when at least :data:`MIN_BLOCKS_S` is left) the
#: block MILP with the time left; the plan covering the most as published (ties: greedy, slots, blocks).
hybrid = best_of("hybrid", Stage("greedy", greedy_stage), Stage("slots", slots_stage),
                 Stage("blocks", blocks_stage, min_left_s=MIN_BLOCKS_S))

register("greedy", greedy_schedule)
register("slots", with_upper_bound(slots_from_greedy))
register("blocks", with_upper_bound(blocks))
register("milp", with_upper_bound(blocks))  # the old name of blocks
register("hybrid", with_upper_bound(hybrid))
