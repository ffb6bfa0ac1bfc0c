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
  make a work second about a second of this machine's time, quiet
  (``benchmarks/results/quality/deterministic_budget/``): ``time_limit_s`` keeps its
  meaning there, on a loaded machine the same work takes longer.

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
           "HIGHS_SOLVE_S", "HIGHS_NONZERO_S", "HIGHS_CHECK_S", "WORK_UNIT"]

#: Ticks per work second (a tick is a microsecond of nominal time).
TICKS_PER_S = 1_000_000
#: The unit plan documents name (``metrics.budget.unit``).
WORK_UNIT = "work_s"

#: (A2) A HiGHS solve costs ``HIGHS_SOLVE_S + HIGHS_NONZERO_S * nnz + checks * max(HIGHS_CHECK_MIN_S,
#: HIGHS_CHECK_S * nnz)`` work seconds: a fixed cost, its setup and presolve in proportion to the model's nonzeros,
#: and its search: HiGHS checks its limits (the interrupt callback, with one thread) at every node and every round
#: of the root's cuts and heuristics, each check's work again in proportion to the model's size (at least
#: ``HIGHS_CHECK_MIN_S``).  Fitted to the CPU seconds of 350 solves of the default plan on ten shared maps (slot
#: and detection grids, LNS slices, interval bound; ``benchmarks/speed/deterministic_budget_calibrate.py``): the sum
#: within 1 %, a map's solves within a factor 0.25-2.
HIGHS_SOLVE_S = 0.005
HIGHS_NONZERO_S = 1.15e-5
HIGHS_CHECK_S = 4.5e-7
HIGHS_CHECK_MIN_S = 0.001

#: (A3) Nominal work seconds of the Python steps the stages' budgets see: ``(per call, per item)``, the item named
#: in the comment.  Least squares of their CPU seconds on ten shared maps (``benchmarks/speed/deterministic_budget_calibrate.py``).
STEP_COSTS: dict[str, tuple[float, float]] = {
    "greedy": (0.005, 0.00013),      # per candidate field
    "execute": (0.004, 0.00104),     # the telescope's executor on a plan's queues: per exposure
    "score": (0.008, 0.00011),       # expected detections (X1) of a plan: per exposure
    "timing": (0.003, 0.00005),      # a slot solution timed with the real overheads: per exposure
    "grid": (0.0005, 0.0),           # a slot grid's instance and model
    "reach": (0.015, 0.000002),      # the detection model's reaches and levels: per eligible (field, slot) pair
    "slice": (0.005, 0.0000026),     # an LNS slice's model, its times and rule check: per nonzero
    "bound_round": (0.002, 0.0),     # a separation round of the interval bound
}


def highs_work(nonzeros: int, checks: int) -> int:
    """(A2) Ticks of a HiGHS solve of a model with ``nonzeros`` that made ``checks`` limit checks so far."""
    work = HIGHS_SOLVE_S + HIGHS_NONZERO_S * nonzeros + checks * max(HIGHS_CHECK_MIN_S, HIGHS_CHECK_S * nonzeros)
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
        """A solve's limit of ``seconds`` work seconds, in ticks."""
        return int(round(max(float(seconds), 0.0) * TICKS_PER_S))


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

    def __init__(self, clock: WorkClock, nonzeros: int, limit_s: float) -> None:
        self.clock, self.nonzeros = clock, int(nonzeros)
        self.limit = clock.ticks_for(limit_s)
        self.checks = 0
        self.stopped = False

    @property
    def wall_guard_s(self) -> float:
        """The solve's wall-clock limit (A5)."""
        return max(WALL_GUARD_MIN_S, WALL_GUARD_FACTOR * self.limit / TICKS_PER_S)

    def reached(self) -> bool:
        """Count one limit check; True (and remembered) once the solve's work reaches its limit."""
        self.checks += 1
        self.stopped = self.stopped or highs_work(self.nonzeros, self.checks) >= self.limit
        return self.stopped

    def charge(self, gurobi_work: float | None = None) -> None:
        """Charge the clock the solve's work (A2): HiGHS's checks, or Gurobi's own work units (its ``Work``)."""
        if gurobi_work is not None:
            self.clock.charge_ticks(self.clock.ticks_for(gurobi_work))
        else:
            self.clock.charge_ticks(highs_work(self.nonzeros, self.checks))


def wall_stop(clock: Clock | None) -> str:
    """(A5) The status of a solve its wall-clock limit stopped, ``time_limit``; on a work clock that was the guard,
    and the clock remembers it (the plan then depends on the load)."""
    if isinstance(clock, WorkClock):
        clock.interrupted = True
    return "time_limit"


def solve_work(clock: Clock | None, nonzeros: int, limit_s: float) -> SolveWork | None:
    """The :class:`SolveWork` of a solve on ``clock``; None on the wall clock (or no clock): a time limit."""
    return SolveWork(clock, nonzeros, limit_s) if isinstance(clock, WorkClock) else None
