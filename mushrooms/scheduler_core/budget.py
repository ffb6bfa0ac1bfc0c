"""The optimisation's budget: the clock every stage reads instead of ``time.perf_counter()``.

A plan's stages decide from "time left": the hybrid's stage allocation, the
slot grids' shares, the LNS slices and its idle stop, the detection grids,
the block MILP's re-solves, the interval bound's rounds.  They read a
:class:`Clock` (``problem.clock``, one per optimisation) instead of the wall
clock (``docs/design/milp.md`` section 7, A1-A5):

- :class:`WallClock` (``[scheduler] deterministic = false``): seconds of wall
  time, as before; a plan then depends on the machine's load.
- :class:`WorkClock` (``deterministic = true``): "work seconds" that advance
  only by deterministic work (A2, A3): each HiGHS solve by its own progress
  (the limit checks it makes, on a model of so many nonzeros), each Python
  step by a fixed nominal cost.  A stage's budget is then a count of work, and
  a plan depends only on its inputs and the configuration.  The rates below
  make a work second about a CPU second of the reference machine (2 cores,
  HiGHS 1.16; ``benchmarks/results/quality/deterministic_budget/calibration.txt``):
  ``time_limit_s`` keeps about its meaning there when it is quiet; on a loaded
  machine the same work, and the same plan, takes longer.

Work is counted in integer ticks (microseconds of nominal time): a stage's
``since(mark)`` is then exact, whatever the clock counted before.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Iterator

__all__ = ["Clock", "WallClock", "WorkClock", "SolveWork", "new_clock", "solve_work", "wall_stop", "highs_work",
           "STEP_COSTS",
           "TICKS_PER_S", "WALL_GUARD_FACTOR", "WALL_GUARD_MIN_S", "HIGHS_CHECK_MIN_S",
           "HIGHS_SOLVE_S", "HIGHS_NONZERO_S", "HIGHS_ITERATION_S", "HIGHS_ITERS_PER_CHECK", "WORK_UNIT"]

#: Ticks per work second (a tick is a microsecond of nominal time).
TICKS_PER_S = 1_000_000
#: The unit plan documents name (``metrics.budget.unit``).
WORK_UNIT = "work_s"

#: (A2) A HiGHS solve costs ``HIGHS_SOLVE_S + HIGHS_NONZERO_S * nnz + max(HIGHS_CHECK_MIN_S * checks,
#: HIGHS_ITERATION_S * (rows + cols) * iterations)`` work seconds: a fixed cost, its setup in proportion to the
#: model's nonzeros, and its search, the simplex iterations of its LPs, each in proportion to the LP's size, and at
#: least ``HIGHS_CHECK_MIN_S`` for each of its limit checks (HiGHS checks its limits, the interrupt callback, at
#: every node and every round of the root's cuts and heuristics).  The callback does not report the LP iterations
#: (``simplex_iteration_count`` is -1 there in HiGHS 1.16): while a solve runs they are counted as
#: ``HIGHS_ITERS_PER_CHECK`` per check (about the median of the solves that make many checks, 46, and their 90th
#: percentile, 148), and once it ends as HiGHS's own count.  Least squares of the CPU seconds of 472 solves of the
#: default plan on 16 shared maps (slot and detection grids, LNS slices, interval bound;
#: ``benchmarks/deterministic_budget_calibrate.py``): the sum within 1 %, a map's within a factor 0.4-1.8.
HIGHS_SOLVE_S = 0.02
HIGHS_NONZERO_S = 1e-6
HIGHS_ITERATION_S = 5e-8
HIGHS_CHECK_MIN_S = 0.001
HIGHS_ITERS_PER_CHECK = 100

#: (A3) Nominal work seconds of the Python steps the stages' budgets see: ``(per call, per item)``, the item named
#: in the comment.  Least squares of their CPU seconds on 16 shared maps (``benchmarks/deterministic_budget_calibrate.py``).
STEP_COSTS: dict[str, tuple[float, float]] = {
    "greedy": (0.005, 0.00013),      # per candidate field
    "execute": (0.004, 0.00104),     # the telescope's executor on a plan's queues: per exposure
    "score": (0.008, 0.00011),       # expected detections (X1) of a plan: per exposure
    "timing": (0.002, 0.0001),       # a slot solution timed with the real overheads: per exposure
    "grid": (0.0005, 0.0),           # a slot grid's instance and model
    "reach": (0.015, 0.000002),      # the detection model's reaches and levels: per eligible (field, slot) pair
    "slice": (0.005, 0.0000026),     # an LNS slice's model, its times and rule check: per nonzero
    "bound_round": (0.002, 0.0),     # a separation round of the interval bound
}


def highs_work(nonzeros: int, size: int, checks: int, iterations: int | None = None) -> int:
    """(A2) Ticks of a HiGHS solve of a model with ``nonzeros`` and ``size`` rows and columns that made ``checks``
    limit checks and ``iterations`` LP iterations so far (None: while it runs, ``HIGHS_ITERS_PER_CHECK`` a check)."""
    iterations = HIGHS_ITERS_PER_CHECK * checks if iterations is None else iterations
    work = HIGHS_SOLVE_S + HIGHS_NONZERO_S * nonzeros + max(HIGHS_CHECK_MIN_S * checks,
                                                            HIGHS_ITERATION_S * size * iterations)
    return int(round(work * TICKS_PER_S))


class Clock:
    """What the stages read: a mark, the budget spent since it, and steps charged (A1).

    ``mark()`` / ``since(mark)`` replace ``time.perf_counter()`` differences;
    ``step(name, items)`` charges a Python step its nominal cost (A3; the wall
    clock ignores it: the step took its own time); ``off_budget()`` is a
    section whose cost no stage sees (the certified bound comes on top of
    ``time_limit_s``).  ``interrupted`` is set when the wall clock stopped a
    work-budget run (A5): its plan then depends on the machine's load.
    """

    kind = "wall"
    unit = "s"

    def __init__(self) -> None:
        self.off = 0  # what the off-budget sections cost, in the clock's own units
        self.interrupted = False

    def _now(self) -> float:
        raise NotImplementedError

    def mark(self) -> tuple[float, float]:
        """An opaque mark to measure the budget spent from."""
        return self._now(), self.off

    def since(self, mark: tuple[float, float]) -> float:
        """Budget spent (s, or work s) since ``mark``, the off-budget sections left out."""
        now, off = mark
        return self._seconds((self._now() - now) - (self.off - off))

    def _seconds(self, amount: float) -> float:
        return float(amount)

    def step(self, name: str, items: int = 0) -> None:
        """Charge the Python step ``name`` on ``items`` (:data:`STEP_COSTS`); nothing on the wall clock."""

    def charge_ticks(self, ticks: int) -> None:
        """Charge solver work (ticks); nothing on the wall clock."""

    @contextmanager
    def off_budget(self) -> Iterator[None]:
        """A section no stage's budget is charged for (the certified bound)."""
        start = self._now()
        try:
            yield
        finally:
            self.off += self._now() - start

    def record(self, spent: float | None = None) -> dict:
        """``metrics.budget`` of a plan made under this clock; ``spent`` the optimisation's (work clock only)."""
        out: dict = {"kind": self.kind, "unit": self.unit}
        if self.kind == "work":
            out["spent"] = None if spent is None else round(spent, 6)
        out["interrupted"] = self.interrupted
        return out


class WallClock(Clock):
    """Seconds of wall time (``time.perf_counter()``): the budget of ``deterministic = false``."""

    def _now(self) -> float:
        return time.perf_counter()


class WorkClock(Clock):
    """Work seconds (A2, A3), counted in integer ticks: the budget of ``deterministic = true``."""

    kind = "work"
    unit = WORK_UNIT

    def __init__(self) -> None:
        super().__init__()
        self.ticks = 0

    def _now(self) -> int:
        return self.ticks

    def _seconds(self, amount: float) -> float:
        return amount / TICKS_PER_S

    def step(self, name: str, items: int = 0) -> None:
        base, per_item = STEP_COSTS[name]
        self.ticks += int(round((base + per_item * max(int(items), 0)) * TICKS_PER_S))

    def charge_ticks(self, ticks: int) -> None:
        self.ticks += int(ticks)

    def ticks_for(self, seconds: float) -> int:
        """A solve's limit of ``seconds`` work seconds, in ticks (an infinite one: more than any solve does)."""
        seconds = max(float(seconds), 0.0)
        return int(round(seconds * TICKS_PER_S)) if seconds < 1e12 else 10**18


def new_clock(deterministic: bool) -> Clock:
    """A fresh clock: :class:`WorkClock` when ``deterministic``, else :class:`WallClock`."""
    return WorkClock() if deterministic else WallClock()


#: (A5) A solve on the work clock still gets a wall-clock limit, this many times its work limit (at least
#: :data:`WALL_GUARD_MIN_S`): a solver phase that makes no limit check (presolve) cannot run unbounded.  A plan
#: the guard stopped says so (``metrics.budget.interrupted``).
WALL_GUARD_FACTOR = 30.0
WALL_GUARD_MIN_S = 60.0


class SolveWork:
    """(A2) One HiGHS solve on a :class:`WorkClock`: its limit checks counted, stopped at its work limit.

    ``reached()`` is asked at each of HiGHS's limit checks (the interrupt
    callback); ``charge()`` charges the clock the solve's work once it ends.
    """

    def __init__(self, clock: WorkClock, nonzeros: int, size: int, limit_s: float) -> None:
        self.clock, self.nonzeros, self.size = clock, int(nonzeros), int(size)
        self.limit = clock.ticks_for(limit_s)
        self.checks = self.iterations = 0
        self.stopped = False

    @property
    def wall_guard_s(self) -> float:
        """The solve's wall-clock limit (A5)."""
        return max(WALL_GUARD_MIN_S, WALL_GUARD_FACTOR * self.limit / TICKS_PER_S)

    def reached(self) -> bool:
        """Count one limit check; True (and remembered) once the solve's work reaches its limit."""
        self.checks += 1
        self.stopped = self.stopped or highs_work(self.nonzeros, self.size, self.checks) >= self.limit
        return self.stopped

    def charge(self, gurobi_work: float | None = None, iterations: int = 0) -> None:
        """Charge the clock the solve's work (A2): HiGHS's checks and LP ``iterations``, or Gurobi's own work
        units (its ``Work``)."""
        self.iterations = int(iterations)
        if gurobi_work is not None:
            self.clock.charge_ticks(self.clock.ticks_for(gurobi_work))
        else:
            self.clock.charge_ticks(highs_work(self.nonzeros, self.size, self.checks, self.iterations))


def wall_stop(clock: Clock | None) -> str:
    """(A5) The status of a solve its wall-clock limit stopped, ``time_limit``; on a work clock that was the guard,
    and the clock remembers it (the plan then depends on the load)."""
    if isinstance(clock, WorkClock):
        clock.interrupted = True
    return "time_limit"


def solve_work(clock: Clock | None, nonzeros: int, size: int, limit_s: float) -> SolveWork | None:
    """The :class:`SolveWork` of a solve on ``clock`` (a model of ``nonzeros`` and ``size`` rows and columns); None
    on the wall clock (or no clock): a time limit."""
    return SolveWork(clock, nonzeros, size, limit_s) if isinstance(clock, WorkClock) else None
