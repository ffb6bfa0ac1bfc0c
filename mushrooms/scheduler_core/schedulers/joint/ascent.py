"""Each telescope alone, and the coordinate ascent of the joint plan (``docs/design/telescopes.md``, J5, J6).

A *step* is one of today's single-telescope plans (greedy, then the slot
portfolio started from it: :func:`~..portfolio.portfolio.slots_from_greedy`;
greedy alone for a one-filter, one-visit rule)
of one telescope on re-weighted pixels, on a fresh clock of its own with at
most its own ``time_limit_s``: on the work clock (``[scheduler]
deterministic``) a step, and so the whole ascent, depends only on its
inputs, never on the machine's load.

(J6) The ascent's first sweep starts from one telescope's plan alone and
solves every other telescope on the pixels the plans fixed so far leave
uncovered (gwemopt's iterative tiling); the later sweeps re-solve each
telescope with the others fixed, keeping a step only when the union rises,
until a sweep brings nothing.  The ascent is run from each telescope in
turn, the best alone first, until the budget is spent, and the best end is
kept.  The
union never falls, so the plan covers at least what the best telescope
covers alone, and at least each first sweep (the tiling starting from any
telescope) that the budget allowed.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ...budget import new_clock
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from ..greedy.schedule import greedy_schedule
from ..portfolio.portfolio import slots_from_greedy
from .cells import covered_pixels

__all__ = ["plan_alone", "coordinate_ascent", "iterative_tiling", "union_of", "masked", "Ascent", "MAX_SWEEPS",
           "STEP_MIN_S"]

#: (J6) Most sweeps of the ascent (the first is the iterative tiling).
MAX_SWEEPS = 3
#: (J6) No step starts with less budget (s) left than this.
STEP_MIN_S = 0.3


def nothing(solver: str = "joint:none", status: str = "no_window") -> ScheduleResult:
    """The empty schedule of a telescope that observes nothing."""
    return ScheduleResult((), solver, status)


def plan_alone(problem: PlanningProblem, weight: np.ndarray | None = None, time_limit_s: float | None = None,
               should_stop: StopCheck | None = None, greedy: bool = False) -> tuple[ScheduleResult, float]:
    """One telescope's single-telescope plan on pixel weights ``weight`` (default the map), on a fresh clock.

    ``greedy``: greedy's plan alone (``solver = "greedy"``: no MILP).

    Returns
    -------
    result : ScheduleResult
        Empty (status ``no_window``) for a telescope with no candidate or
        whose candidates weigh nothing.
    spent : float
        Budget (s, on the step's clock: work or wall seconds) it took.
    """
    w = problem.prob if weight is None else np.asarray(weight, float)
    if problem.field_ids.size == 0:
        return nothing(), 0.0
    if not np.any(problem.footprints.field_probability(w) > 0):
        return nothing(status="nothing_left"), 0.0
    cfg = problem.config
    if time_limit_s is not None and float(time_limit_s) != cfg.time_limit_s:
        t, detection = float(time_limit_s), cfg.detection_time_limit_s
        if detection >= t:  # the detection stage's limit must stay below time_limit_s: its share of the budget
            detection = detection / cfg.time_limit_s * t
        cfg = dataclasses.replace(cfg, time_limit_s=t, detection_time_limit_s=detection)
    step = dataclasses.replace(problem, config=cfg, prob=w, clock=new_clock(cfg.deterministic))
    mark = step.clock.mark()
    # (J3) a one-visit rule (one filter) is greedy's alone: the slot model plans sequences of two visits or more
    result = slots_from_greedy(step, should_stop) if len(cfg.filters) >= 2 and not greedy \
        else greedy_schedule(step, should_stop)
    return result, step.clock.since(mark)


def _fields(result: ScheduleResult) -> list[int]:
    return list(dict.fromkeys(o.field_id for o in result.observations))


def union_of(problems: Sequence[PlanningProblem], results: Sequence[ScheduleResult], weight: np.ndarray) -> float:
    """(J1) ``Σ_l w_l y_l`` of the results together: every pixel any telescope covers, once."""
    mask = np.zeros(weight.size, bool)
    for problem, result in zip(problems, results):
        mask[covered_pixels(problem, _fields(result))] = True
    return float(weight[mask].sum())


def masked(weight: np.ndarray, problems: Sequence[PlanningProblem], results: Sequence[ScheduleResult],
           skip: int) -> np.ndarray:
    """``weight`` with 0 on the pixels the telescopes other than ``skip`` cover."""
    w = np.array(weight, float)
    for i, (problem, result) in enumerate(zip(problems, results)):
        if i != skip:
            w[covered_pixels(problem, _fields(result))] = 0.0
    return w


@dataclass
class Ascent:
    """What the ascent did: the plans kept, the budget it spent and every step's union."""

    results: list[ScheduleResult]
    union: float
    spent: float = 0.0
    steps: list[dict] = field(default_factory=list)


def _step(problems: Sequence[PlanningProblem], run: Ascent, i: int, weight: np.ndarray, budget_s: float,
          should_stop: StopCheck | None, sweep: int, greedy: bool = False) -> bool | None:
    """Re-solve telescope ``i`` with the others fixed; True when the union rose (kept), None when out of budget."""
    left = budget_s - run.spent
    if left < STEP_MIN_S or (should_stop is not None and should_stop()):
        return None
    w = masked(weight, problems, run.results, i)
    result, cost = plan_alone(problems[i], w, min(problems[i].config.time_limit_s, left), should_stop, greedy)
    run.spent += cost
    trial = run.results[:i] + [result] + run.results[i + 1:]
    value = union_of(problems, trial, weight)
    run.steps.append({"sweep": sweep, "telescope": i, "union": round(value, 6), "spent": round(cost, 3)})
    if value > run.union + 1e-12:  # a step is kept only when the union rises
        run.results, run.union = trial, value
        return True
    return False


def coordinate_ascent(problems: Sequence[PlanningProblem], alone: Sequence[ScheduleResult], weight: np.ndarray,
                      budget_s: float, should_stop: StopCheck | None = None, greedy: bool = False) -> Ascent:
    """(J6) The coordinate ascent from the telescopes' plans alone, within ``budget_s``.

    The ascent is run from each telescope's plan alone in turn, the best
    alone first, within one budget, and the best end kept: its first sweep
    is the iterative tiling with that telescope first (the others in the
    order of their plans alone), the later sweeps go on while one raises
    the union.

    Parameters
    ----------
    problems : sequence of PlanningProblem
    alone : sequence of ScheduleResult
        Each telescope's plan alone (:func:`plan_alone`).
    weight : numpy.ndarray
        Pixel weights of J1 (J5: 0 where done).
    budget_s : float
        Budget (s) of all the steps; each step gets at most its telescope's
        ``time_limit_s``.
    greedy : bool
        Every step greedy's plan (``solver = "greedy"``).
    """
    T = len(problems)
    alone_union = [union_of([p], [r], weight) for p, r in zip(problems, alone)]
    order = [i for i in sorted(range(T), key=lambda i: (-alone_union[i], i)) if problems[i].field_ids.size]
    best: Ascent | None = None
    spent, steps = 0.0, []
    for first in order or [0]:
        run = Ascent([alone[i] if i == first else nothing(status="not_yet") for i in range(T)], alone_union[first],
                     spent)
        finished = _ascend(problems, run, order, first, weight, budget_s, should_stop, greedy)
        spent, steps = run.spent, steps + run.steps
        if best is None or run.union > best.union + 1e-12:
            best = run
        if not finished:
            break
    best.spent, best.steps = spent, steps
    return best


def _ascend(problems: Sequence[PlanningProblem], run: Ascent, order: list[int], first: int, weight: np.ndarray,
            budget_s: float, should_stop: StopCheck | None, greedy: bool = False) -> bool:
    """Sweeps from ``first``'s plan alone (the first one the iterative tiling); False when the budget ran out."""
    for sweep in range(MAX_SWEEPS):
        out = [_step(problems, run, i, weight, budget_s, should_stop, sweep, greedy)
               for i in order if not (sweep == 0 and i == first)]
        if None in out:
            return False
        if sweep > 0 and not any(out):
            break
    return True


def iterative_tiling(problems: Sequence[PlanningProblem], weight: np.ndarray,
                     should_stop: StopCheck | None = None) -> list[ScheduleResult]:
    """gwemopt's iterative tiling: the telescopes in the order given, each on what the ones before left.

    Each telescope gets its own ``time_limit_s``; a baseline for the
    benchmarks, the first sweep of :func:`coordinate_ascent` in a fixed order.
    """
    results = [nothing(status="not_yet") for _ in problems]
    for i, problem in enumerate(problems):
        results[i], _ = plan_alone(problem, masked(weight, problems, results, i), None, should_stop)
    return results
