"""Schedulers made of schedulers: the slot scheduler seeded by greedy, the hybrid portfolio, the bound.

A scheduler (:data:`~...problem.Scheduler`) is ``scheduler(problem,
should_stop) -> ScheduleResult``.  A :class:`Stage` is one step of a
composition: it also sees the results of the stages before it and the
budget (s) left of ``config.time_limit_s``, on ``problem.clock`` (wall or
work seconds, :mod:`..budget`).  :func:`best_of` runs stages in
turn and keeps the plan that, as it will be published (after the
least-gain rule), covers the most probability, the earliest stage winning
a tie; :func:`with_upper_bound` attaches the certified coverage bound
(:mod:`..bounds.certified_bound`: the least of U4 and the interval bound V) to a
scheduler's result.  A portfolio given a ``bound`` computes it after its
first stage and skips the stages left once a plan reaches it (within
:data:`BOUND_RTOL`): that plan is then optimal, no stage can beat it.  The named schedulers of
:mod:`...solvers_registry` are built from these, and this module registers them there
(``greedy``, ``slots``, ``blocks`` / ``milp``, ``hybrid``; the hybrid's ``lns`` stage is
:mod:`.lns`, equations H1-H5).

The MILP modules are imported by the stages when they run (and looked up
there, so a test can replace ``slot_schedule.slot_schedule``).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass
from typing import Callable, Mapping

from ...config import PlanningConfig
from ...problem import PlanningProblem, PortfolioEntry, ScheduleResult, Scheduler, StopCheck, UpperBound
from ...solvers_registry import register
from ..gain import published_coverage
from ..greedy.schedule import greedy_schedule

__all__ = ["Stage", "StageRun", "Portfolio", "best_of", "with_upper_bound", "greedy_stage", "slots_stage",
           "paced_slots_stage", "paced_cadence", "PACED_SLOTS_LIMIT_S",
           "blocks_stage", "slots_from_greedy", "blocks", "hybrid", "MIN_BLOCKS_S", "BLOCKS_LIMIT_S", "BOUND_RTOL", "reaches_bound",
           "published_bound"]

log = logging.getLogger(__name__)

#: The hybrid runs the block MILP only when at least this much (s) of its budget is left.
MIN_BLOCKS_S = 1.0

#: The hybrid's block MILP gets at most this long (s).  Measured on the 56 shared maps (coverage objective,
#: 10 s, LNS idle stop 3 s; the block stage's run over 56 shared maps): given what was left, it ran
#: on 34 maps for 87 s in all and beat the stages before it on 7, by at most 0.0026; six of those wins took
#: under 0.25 s, the seventh (bns_o3/18, +0.0026) 10 s.  On the rest it lost by up to 0.31 after up to 9 s.
BLOCKS_LIMIT_S = 1.0

#: The hybrid's slot portfolio at the executor's cadence (:func:`paced_slots_stage`) gets at most this long (s).
PACED_SLOTS_LIMIT_S = 1.5

#: It runs only when at least this much (s) of the budget is left.
MIN_PACED_SLOTS_S = 0.3

#: The hybrid runs the LNS re-solves (:mod:`.lns`) only when at least this much (s) of its budget is left.
MIN_LNS_S = 0.5

#: A plan covering at least ``(1 - BOUND_RTOL)`` of the certified bound (less its margin, B1/B2) is optimal to
#: within that: the portfolio skips its remaining stages.  Tight on purpose: a plan one small pixel short
#: of the bound (a few 1e-6 of coverage on a random test problem) is not optimal, and a later stage finds
#: the pixel; a plan the skip keeps is at most this far (relative) from what the full run would keep.
BOUND_RTOL = 1e-7

#: ``bound(problem) -> UpperBound``: a certified bound on every plan's coverage.
BoundRun = Callable[[PlanningProblem], "UpperBound | None"]

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
    sequences : tuple of (int, int)
        The least and most filters of a sequence the stage plans (F4): with
        a sequence of another length it is skipped.  (2, 2): each field in
        exactly two filters; (2, 8): the slot MILP (G1-G3).
    enabled : callable or None
        ``enabled(config) -> bool``: the stage runs only when it says so
        (None: always); a stage it turns off is not in the portfolio.
    """

    name: str
    run: StageRun
    min_left_s: float | None = None
    sequences: tuple[int, int] = (1, 8)
    enabled: Callable[[PlanningConfig], bool] | None = None

    def plans(self, filters) -> bool:
        """True when the stage plans the sequence ``filters`` (F4)."""
        return self.sequences[0] <= len(tuple(filters)) <= self.sequences[1]


def greedy_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                 earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The greedy scheduler (no budget: it takes well under a second)."""
    return greedy_schedule(problem, should_stop)


def slots_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The slot portfolio with what is left, started from greedy's plan."""
    from ..slots.schedule import slot_schedule

    return slot_schedule(problem, should_stop, start=earlier.get("greedy"), time_limit_s=max(left_s, 0.0))


def paced_slots_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                      earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The slot portfolio planned at the cadence ZTF's scheduler keeps (Q19), at most :data:`PACED_SLOTS_LIMIT_S`.

    The executor opens a filter pass the cadence plus
    :data:`~...telescope.queue_windows.CADENCE_MARGIN_S` after the executed
    first visits of its fields (Q11): a plan whose pairs are packed at the
    cadence loses its last pairs as executed.  This stage plans greedy and
    the slot grids on the problem with ``cadence_s`` widened by that margin
    (:func:`paced_cadence`: at most ``pair_max_s``; greedy's plan there is
    the start); its plan keeps every pair that much
    further apart, so it is a plan of the real problem too, and the
    hybrid's choice (Q15) weighs it by what is executed.
    """
    from ..slots.schedule import slot_schedule

    paced = dataclasses.replace(problem, config=dataclasses.replace(
        problem.config, cadence_s=paced_cadence(problem.config)))
    start = greedy_schedule(paced, should_stop)
    result = slot_schedule(paced, should_stop, start=start, time_limit_s=max(min(left_s, PACED_SLOTS_LIMIT_S), 0.0))
    if not result.observations and start.observations:
        result = dataclasses.replace(start, status=f"{result.status}_greedy_fallback")
    # the published solver says which plan it is: hybrid(slots_paced:highs)
    return dataclasses.replace(result, solver="slots_paced:" + result.solver.split(":", 1)[-1])


def paced_cadence(config: PlanningConfig) -> float:
    """The cadence (s) the paced candidate plans at (Q19): ``cadence_s`` plus the executor's pass margin.

    A ``pair_max_s`` (the longest a pair may span) caps it: the paced pairs
    must still be pairs of the problem.
    """
    from ...telescope.queue_windows import CADENCE_MARGIN_S

    paced = config.cadence_s + CADENCE_MARGIN_S
    return min(paced, config.pair_max_s) if config.pair_max_s else paced


def _paces(config: PlanningConfig) -> bool:
    """The paced candidate runs: switched on, and its cadence is not the plain one (a ``pair_max_s`` at it)."""
    return config.hybrid_paced_slots and paced_cadence(config) > config.cadence_s


def lns_stage(problem: PlanningProblem, should_stop: StopCheck | None,
              earlier: Mapping[str, ScheduleResult], left_s: float,
              max_idle_s: float | None = None) -> ScheduleResult:
    """Large-neighbourhood re-solves (:mod:`.lns`, H1-H5) of the best plan so far with what is left.

    ``max_idle_s``: the seconds without a gain that end them (default
    :data:`.lns.MAX_IDLE_S`).
    """
    from .lns import lns_improve

    names = list(earlier)
    seed = max(names, key=lambda n: (published_coverage(problem, earlier[n]), -names.index(n)))
    idle = {} if max_idle_s is None else {"max_idle_s": max_idle_s}
    return lns_improve(problem, earlier[seed], should_stop, time_limit_s=max(left_s, 0.0),
                       enough=_enough(problem, earlier), **idle)


def _enough(problem: PlanningProblem, earlier: Mapping[str, ScheduleResult]) -> float | None:
    """The coverage past which a stage cannot gain more than ``min_gain`` (V6): the bound less it, if known."""
    bound = next((r.upper_bound for r in earlier.values() if r.upper_bound is not None), None)
    if bound is None:
        return None
    return (1.0 - BOUND_RTOL) * (bound.value - bound.margin) - problem.config.min_gain


def blocks_stage(problem: PlanningProblem, should_stop: StopCheck | None,
                 earlier: Mapping[str, ScheduleResult], left_s: float) -> ScheduleResult:
    """The block MILP with what is left, at most :data:`BLOCKS_LIMIT_S`, its re-solves included.

    Its solve stops as soon as its bound proves no block plan covers more
    than the best plan of the stages before it plus ``min_gain`` (V6; the
    result is then empty, status ``cutoff``).

    It is a coverage scheduler: its budget is that, whatever the objective
    (a detection config would refuse a budget shorter than its detection
    stage's share).
    """
    from ..blocks.schedule import milp_schedule

    limit = min(left_s, BLOCKS_LIMIT_S)
    timed = dataclasses.replace(problem, config=dataclasses.replace(
        problem.config, time_limit_s=limit, objective="coverage"))
    # (V6) it matters only if it beats the best plan so far by min_gain: its solve stops once its bound says no
    best = max((published_coverage(problem, r) for r in earlier.values()), default=None)
    cutoff = None if best is None or problem.config.penalty else best + problem.config.min_gain
    return milp_schedule(timed, should_stop, total_s=limit, cutoff=cutoff)  # re-solves within the budget too


def reaches_bound(coverage: float, bound: UpperBound, min_gain: float = 0.0) -> bool:
    """True when no plan can cover more than ``coverage + min_gain``: within that of the certified ``bound``.

    ``min_gain`` 0: within :data:`BOUND_RTOL` (relative) of the bound, the plan is optimal (V6).
    """
    return coverage >= (1.0 - BOUND_RTOL) * (bound.value - bound.margin) - min_gain


@dataclass(frozen=True)
class Portfolio:
    """Run stages in turn; keep the plan covering the most as published (a tie: the earlier stage).

    Calling it is a :data:`~...problem.Scheduler`.  The result is the
    winner's, with ``solver`` ``<label>(<winner's solver>)``, the whole
    wall time, ``portfolio`` (each candidate's solver, status, gap and
    published coverage) and ``portfolio_choice`` (the winning stage).

    With a ``bound``, it is computed once after the first stage (its cost
    is not taken from the stages' budget: the bound comes on top of
    ``time_limit_s``, as it did after the scheduler) and is the result's
    ``upper_bound``; when the best plan so far reaches it
    (:func:`reaches_bound`) the stages left are skipped, logged and listed
    in ``details["skipped_at_bound"]`` (only those that would have run:
    a stage switched off by the config, or skipped for the filter sequence
    (``details["skipped_for_sequence"]``, which lists only the stages the
    config switches on), is not listed).  The plan is the one the full run
    would keep: no later stage can cover more, and a tie goes to the
    earlier stage.  ``details["stage_times_s"]``: each stage run's wall
    time (s), and the bound's (``bound``), in the order they ran.
    """

    label: str
    stages: tuple[Stage, ...]
    bound: BoundRun | None = None

    def __call__(self, problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
        t0, start = time.perf_counter(), problem.clock.mark()  # (A1) the wall for the record, the clock to decide
        budget = problem.config.time_limit_s
        ran: dict[str, ScheduleResult] = {}
        covs: dict[str, float] = {}
        upper: UpperBound | None = None
        skipped: list[str] = []
        times: dict[str, float] = {}  # wall time (s) of each stage run, and of the bound
        enabled = [s for s in self.stages if s.enabled is None or s.enabled(problem.config)]
        pair_stages = [s.name for s in enabled if not s.plans(problem.config.filters)]
        if pair_stages:  # (F4) they model another number of exposures per field
            what = ", ".join(f"{s.name} ({_filters_range(s)})" for s in self.stages if s.name in pair_stages)
            log.info("%s: skipped for the sequence %s of %d filters, which these stages' models do not hold: %s",
                     self.label, "-".join(problem.config.filters), len(problem.config.filters), what)
        runnable = [s for s in enabled if s.name not in pair_stages]  # those the config switches on, for its sequence
        for i, stage in enumerate(runnable):
            # (V6) the best plan so far reaches the certified bound, less min_gain: no stage left can beat it
            # by more than the least gain a field must bring
            if upper is not None and covs and reaches_bound(max(covs.values()), upper, problem.config.min_gain):
                skipped = [s.name for s in runnable[i:]]
                within = f" within min_gain {problem.config.min_gain:g}" if problem.config.min_gain else ""
                log.info("%s: %s's plan covers %.4f, the certified bound is %.4f (%s): it is optimal%s, "
                         "skipping %s", self.label, max(covs, key=covs.get), max(covs.values()), upper.value,
                         upper.method, within, ", ".join(skipped))
                break
            left = budget - problem.clock.since(start)  # the bound is off the budget (published_bound)
            if stage.min_left_s is not None:
                stopped = should_stop is not None and should_stop()
                if left < stage.min_left_s or stopped:
                    continue
            t_stage = time.perf_counter()
            ran[stage.name] = within_cap(problem, stage.run(problem, should_stop, ran, left))
            covs[stage.name] = published_coverage(problem, ran[stage.name])
            times[stage.name] = round(time.perf_counter() - t_stage, 3)
            if self.bound is not None and upper is None:
                t_bound = time.perf_counter()
                upper = self.bound(problem)
                times["bound"] = round(time.perf_counter() - t_bound, 3)
                if ran[stage.name].upper_bound is None:  # the stages after see it (an LNS stops at it)
                    ran[stage.name] = dataclasses.replace(ran[stage.name], upper_bound=upper)
        from ..as_executed import AS_EXECUTED_MEMO

        name, executed, memo = choose_as_executed(problem, ran, covs)
        best = ran[name]
        entries = tuple(PortfolioEntry(n, r.solver, r.status, r.mip_gap, covs[n]) for n, r in ran.items())
        details = dict(best.details, stage_times_s=times, coverage_as_executed=executed, **{AS_EXECUTED_MEMO: memo})
        if skipped:
            details["skipped_at_bound"] = skipped
        if pair_stages:
            details["skipped_for_sequence"] = pair_stages
        return dataclasses.replace(best, solver=f"{self.label}({best.solver})", runtime_s=time.perf_counter() - t0,
                                   portfolio=entries, portfolio_choice=name, details=details,
                                   upper_bound=upper if upper is not None else best.upper_bound)


def within_cap(problem: PlanningProblem, result: ScheduleResult) -> ScheduleResult:
    """(S4) ``result``, or, when its exposures pass ``max_open_shutter_s``, no plan (status ``<status>_over_cap``).

    A stage whose model holds no S4 row (the LNS's continuous model, the
    block MILP) is kept only when its plan stays within the cap; the
    greedy and slot stages never pass it.
    """
    cap = problem.config.max_open_shutter_s
    if cap is None or sum(o.exposure_s for o in result.observations) <= cap + 1e-6:
        return result
    log.info("%s: its plan's %.0f s of open shutter pass the cap of %.0f s: not a candidate", result.solver,
             sum(o.exposure_s for o in result.observations), cap)
    return dataclasses.replace(result, observations=(), status=f"{result.status}_over_cap")


def choose_as_executed(problem: PlanningProblem, ran: dict[str, ScheduleResult], covs: dict[str, float]
                       ) -> tuple[str, dict[str, float], dict[tuple, float]]:
    """(Q15) the candidate whose queues ZTF's scheduler executes best (cadence-valid coverage), ties to the planned.

    A sequence of three or more filters is judged first by the coverage its
    sequences keep whole as executed (Q21, a sequence F10 cut counting
    whole once its visits are done: :func:`~..as_executed.planned_sequence_coverage`),
    then by the cadence-valid coverage (F1).  Candidates are tried in
    order of planned coverage (then stage order); a plan's executed
    coverage (and its whole sequences') never exceeds its planned one, so
    the search stops at the first candidate whose planned coverage is no
    better than the best value so far.

    Returns
    -------
    (str, dict of str to float, dict of tuple to float)
        The chosen stage, the executed coverage of each candidate tried, and
        the same by :func:`~..as_executed.execution_key` (the memo that
        spares the published plan a second run of the executor; with a
        sequence, its whole sequences' value under the key with
        ``"sequence"`` appended).
    """
    from ..as_executed import AS_EXECUTED_MEMO, keyed_coverages_as_executed

    names = list(ran)
    order = sorted(names, key=lambda n: (-covs[n], names.index(n)))
    executed: dict[str, float] = {}
    whole: dict[str, float] = {}  # the value judged first: the sequences' (Q21), or the pair's
    memo: dict[tuple, float] = {}
    for n in names:  # what a stage already knows (the LNS scores its seed and its plans as executed)
        memo.update((ran[n].details or {}).get(AS_EXECUTED_MEMO, {}))
    for n in order:
        if whole and covs[n] <= max(whole.values()) + 1e-12:
            break
        key, value, kept = keyed_coverages_as_executed(problem, ran[n], memo)  # an LNS that kept its seed: one run
        executed[n], whole[n] = round(value, 6), round(kept, 6)
        if key is not None:
            memo[key] = value
    name = max(executed, key=lambda n: (whole[n], executed[n], covs[n], -names.index(n)))
    return name, executed, memo


def _filters_range(stage: Stage) -> str:
    """What a stage plans, e.g. ``2 filters`` or ``2-8 filters`` (F4)."""
    lo, hi = stage.sequences
    return f"{lo} filters" if lo == hi else f"{lo}-{hi} filters"


def best_of(label: str, *stages: Stage, bound: BoundRun | None = None) -> Portfolio:
    """The :class:`Portfolio` of ``stages``, its results' solver named ``label(...)``; ``bound``: stop at it."""
    return Portfolio(label, tuple(stages), bound)


def slots_from_greedy(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
    """Greedy, then the slot portfolio started from it with the budget left.

    When the slot portfolio ends without a plan and greedy has one, the
    greedy plan is returned under the slot scheduler's name, status
    ``<status>_greedy_fallback``.
    """
    t0, start = time.perf_counter(), problem.clock.mark()
    greedy = greedy_stage(problem, should_stop, {}, problem.config.time_limit_s)
    left = problem.config.time_limit_s - problem.clock.since(start)
    slots = slots_stage(problem, should_stop, {"greedy": greedy}, left)
    if not slots.observations and greedy.observations:
        slots = dataclasses.replace(slots, status=f"{slots.status}_greedy_fallback",
                                    observations=greedy.observations,
                                    details=dict(slots.details, greedy_details=greedy.details))
    return dataclasses.replace(slots, runtime_s=time.perf_counter() - t0)


def blocks(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
    """The block MILP with the whole budget."""
    from ..blocks.schedule import milp_schedule

    return milp_schedule(problem, should_stop)


def published_bound(problem: PlanningProblem) -> UpperBound | None:
    """The certified bound plans publish: ``min(U4, V)`` within ``config.bound_time_limit_s`` (:mod:`..bounds.certified_bound`).

    (F5) A sequence of ``k >= 2`` filters keeps the pair's bound: its first
    two visits are a plan of the pair (the later ones only take time), so
    the pair's relaxations hold.  A one-filter sequence (a field costs one
    exposure) has its own: U5, U6 and V8 (``docs/design/milp.md``).
    """
    from ..bounds.certified_bound import certified_upper_bound

    with problem.clock.off_budget():  # (A1) on top of time_limit_s: no stage's budget pays for it
        return certified_upper_bound(problem)


def with_upper_bound(scheduler: Scheduler) -> Scheduler:
    """``scheduler`` whose result carries the certified coverage upper bound of the problem (:func:`published_bound`).

    A result that already holds one (a portfolio with a ``bound``) keeps it.
    """

    def bounded(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
        result = scheduler(problem, should_stop)
        if result.upper_bound is not None:
            return result
        return dataclasses.replace(result, upper_bound=published_bound(problem))

    bounded.__name__ = bounded.__qualname__ = f"with_upper_bound({getattr(scheduler, '__name__', scheduler)!s})"
    bounded.__doc__ = scheduler.__doc__
    return bounded


#: The hybrid: greedy, the slot portfolio from it, (with ``config.hybrid_paced_slots``) the slot portfolio at the
#: executor's cadence (:func:`paced_slots_stage`, at most :data:`PACED_SLOTS_LIMIT_S`), (with
#: ``config.hybrid_lns``) the LNS re-solves (:mod:`.lns`) of the best plan so far with the time left (they stop
#: early once a round of slices or 1 s bring nothing), then (with ``config.hybrid_blocks``, when at least
#: :data:`MIN_BLOCKS_S` is left) the block MILP with the time left, at most :data:`BLOCKS_LIMIT_S`; of their plans
#: the one ZTF's scheduler executes best (Q15; ties: the planned coverage, then greedy, slots, slots_paced, lns,
#: blocks; the LNS only returns a plan other than its seed when it covers more).
#: The certified bound is computed after greedy, and the stages left are skipped once a plan reaches it.
hybrid = best_of("hybrid", Stage("greedy", greedy_stage), Stage("slots", slots_stage, sequences=(2, 8)),
                 Stage("slots_paced", paced_slots_stage, min_left_s=MIN_PACED_SLOTS_S, sequences=(2, 2),
                       enabled=_paces),
                 Stage("lns", lns_stage, min_left_s=MIN_LNS_S, sequences=(2, 2),
                       enabled=lambda config: config.hybrid_lns),
                 Stage("blocks", blocks_stage, min_left_s=MIN_BLOCKS_S, sequences=(2, 2),
                       enabled=lambda config: config.hybrid_blocks), bound=published_bound)

register("greedy", greedy_schedule)
register("slots", with_upper_bound(slots_from_greedy))
register("blocks", with_upper_bound(blocks))
register("milp", with_upper_bound(blocks))  # the old name of blocks
register("hybrid", with_upper_bound(hybrid))
