"""One call from a sky map to a checked plan: ``make_plan``."""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from typing import Callable, Collection, Mapping

import numpy as np

from astropy.time import Time, TimeDelta

from .plan.checker import check_plan
from .config import PlanningConfig
from .errors import InputError, PlanCheckError
from .schedulers.gain import drop_low_gain
from .schedulers.portfolio.portfolio import MIN_BLOCKS_S  # noqa: F401  (the hybrid's; re-exported)
from .plan.localization import with_map_details
from .plan.document import EventInfo, Observation, Plan, PlanMetrics, iso_utc, make_plan_id, sorted_observations
from .budget import Clock, new_clock
from .clock import on_merger_clock
from .source.depth import depth_model
from .prepare import prepare_problem
from .problem import PlanningProblem, ScheduleResult, StopCheck
from .sky.skymap import SkyMap
from .schedulers.as_executed import AS_EXECUTED_MEMO, execution_key, queue_coverages
from .solvers_registry import SOLVER_NAMES, get_scheduler, unknown_solver_message

__all__ = ["make_plan", "build_plan", "run_scheduler", "optimise", "coverage_stage_problem", "greedy_coverage",
           "SOLVERS"]

log = logging.getLogger(__name__)

#: Scheduler names (``milp`` = ``blocks``, the old name kept for old configs): :mod:`.solvers_registry`'s.
SOLVERS = SOLVER_NAMES


def run_scheduler(problem: PlanningProblem, solver: str,
                  should_stop: StopCheck | None = None) -> ScheduleResult:
    """Run one scheduler of the registry (:mod:`.solvers_registry`) on a problem.

    Parameters
    ----------
    problem : PlanningProblem
    solver : str
        ``greedy``; ``slots`` (slot-assignment MILP portfolio, started from
        greedy's plan); ``blocks`` (the paper's block MILP; ``milp`` is an
        alias); ``hybrid``: greedy, then the slot portfolio started from it,
        then (``config.hybrid_paced_slots``) the slot portfolio at the
        cadence ZTF's scheduler keeps (Q19), then (``config.hybrid_lns``)
        the LNS re-solves of the best plan, then (with
        ``config.hybrid_blocks``, when at least :data:`MIN_BLOCKS_S` of
        ``config.time_limit_s`` is left) the block MILP with the time
        left, at most ``BLOCKS_LIMIT_S``; the plan ZTF's scheduler executes
        best is kept (Q15; on a tie the one covering the most as planned,
        then the earlier of greedy, slots, slots_paced, lns, blocks):
        :data:`.schedulers.portfolio.portfolio.hybrid`.
    should_stop : callable, optional
        Polled by every scheduler; True stops the run with the best plan so
        far.

    Returns
    -------
    ScheduleResult
        For the MILP schedulers ``upper_bound`` holds the certified
        coverage bound (:mod:`.schedulers.bounds.coverage_bound`); the hybrid's ``solver``
        names the plan kept (``hybrid(slots:highs)``, ...), its
        ``portfolio`` each candidate's coverage.
    """
    return get_scheduler(solver)(problem, should_stop)


def optimise(problem: PlanningProblem, skymap: SkyMap, solver: str, should_stop: StopCheck | None = None,
             scheduler: Callable[..., ScheduleResult] | None = None) -> ScheduleResult:
    """The whole optimisation of one plan for ``config.objective``, within ``config.time_limit_s``.

    The budgets are read on a fresh clock (:mod:`.budget`): work seconds when
    ``config.deterministic``, else wall seconds.

    ``coverage`` (and ``greedy``, the fast coverage heuristic, whatever the
    objective): the scheduler with the whole budget.  ``detection``: the
    scheduler with ``time_limit_s - detection_time_limit_s``, then the
    detection stage (:func:`~.detection_slots.detection_stage`) with what is
    left of ``time_limit_s`` (at most ``detection_time_limit_s``; the
    certified upper bound comes on top, as for ``coverage``), started
    from the scheduler's coverage plan and kept only above its coverage
    floor (X6: within ``detection_max_coverage_loss`` of it and never below
    the coverage of greedy's plan in the scheduler's portfolio), and above
    the same floor as ZTF's scheduler executes the queues (X10), with more
    expected detections.

    Parameters
    ----------
    problem : PlanningProblem
    skymap : SkyMap
        The map of the problem (the detection stage needs its distance layers).
    solver : str
        Scheduler name (:data:`SOLVERS`).
    should_stop : callable, optional
        Polled by both stages.
    scheduler : callable, optional
        ``run_scheduler``-compatible function (the daemon's planner);
        default :func:`run_scheduler`, looked up at each call.

    Returns
    -------
    ScheduleResult
        ``details["budget"]`` (not for ``greedy``, which has no budget) is
        ``metrics.budget``: the clock's kind and unit (:mod:`.budget`), the
        work spent (work clock), and whether a wall-clock stop ended it.
    """
    scheduler = scheduler or run_scheduler
    # (A1) one fresh clock for the whole optimisation; (A5) a caller's (wall-clock) stop is recorded on it
    problem = dataclasses.replace(problem, clock=new_clock(problem.config.deterministic))
    stop = _recorded_stop(problem.clock, should_stop)
    start = problem.clock.mark()
    result = _optimised(problem, skymap, solver, stop, scheduler)
    if solver == "greedy":  # no budget
        return result
    budget = problem.clock.record(problem.clock.since(start))
    return dataclasses.replace(result, details=dict(result.details, budget=budget))


def _recorded_stop(clock: Clock, should_stop: StopCheck | None) -> StopCheck | None:
    """``should_stop``, which also marks ``clock.interrupted`` when it says stop (A5)."""
    if should_stop is None:
        return None

    def stop() -> bool:
        if should_stop():
            clock.interrupted = True
            return True
        return False

    return stop


def _optimised(problem: PlanningProblem, skymap: SkyMap, solver: str, should_stop: StopCheck | None,
               scheduler: Callable[..., ScheduleResult]) -> ScheduleResult:
    """:func:`optimise` on ``problem``'s own clock."""
    cfg = problem.config
    if cfg.objective != "detection" or solver == "greedy":
        return scheduler(problem, solver, should_stop)
    from .sequences import is_pair

    if not is_pair(cfg.filters):  # (F4) the detection stage plans pairs: a sequence is planned for coverage
        result = scheduler(problem, solver, should_stop)
        log.info("objective detection: the detection stage plans pairs of filters; the sequence %s is planned "
                 "for coverage", "-".join(cfg.filters))
        return dataclasses.replace(result, details=dict(
            result.details, detection_stage=f"skipped: a sequence of {len(cfg.filters)} filters"))
    from .schedulers.detection.stage import detection_stage

    start = problem.clock.mark()
    share = cfg.detection_time_limit_s
    result = scheduler(coverage_stage_problem(problem), solver, should_stop)
    spent = problem.clock.since(start)  # (A1) the bound comes on top: it is off the budget
    left = min(share, cfg.time_limit_s - spent)
    if cfg.exposure_menu_s and result.upper_bound is not None:
        result = dataclasses.replace(result, upper_bound=_menu_upper_bound(problem))
    t_detection = time.perf_counter()
    result = detection_stage(problem, skymap, result, should_stop, time_limit_s=max(left, 0.0),
                             depth=depth_model(cfg),
                             baseline_coverage=greedy_coverage(result),
                             baseline_executed=result.details.get("coverage_as_executed", {}).get("greedy"))
    times = dict(result.details.get("stage_times_s", {}), detection=round(time.perf_counter() - t_detection, 3))
    return dataclasses.replace(result, details=dict(result.details, stage_times_s=times))


def coverage_stage_problem(problem: PlanningProblem) -> PlanningProblem:
    """The problem the coverage scheduler solves under ``objective = "detection"``.

    The coverage objective, ``time_limit_s - detection_time_limit_s`` and
    every visit ``exposure_s`` (no exposure menu): the detection stage
    (:func:`optimise`) then starts from its plan.
    """
    cfg = problem.config
    return dataclasses.replace(problem, config=dataclasses.replace(
        cfg, objective="coverage", time_limit_s=cfg.time_limit_s - cfg.detection_time_limit_s, exposure_menu_s=()))


def greedy_coverage(result: ScheduleResult) -> float | None:
    """Published coverage of greedy's plan in a portfolio's result (the hybrid's first stage); None without one."""
    return next((e.coverage for e in result.portfolio if e.name == "greedy"), None)


def _menu_upper_bound(problem: PlanningProblem):
    """The certified coverage bound of plans whose exposures come from the menu: that of its shortest exposure.

    Every menu exposure lasts at least ``min(exposure_menu_s)``, so a plan of
    menu exposures has no more pairable fields (U1) and fits no more
    exposures in a segment (U2) than one of the shortest: the bound of the
    shortest bounds them all.
    """
    from .schedulers.bounds.coverage_bound import coverage_upper_bound

    cfg = problem.config
    shortest = dataclasses.replace(cfg, exposure_s=float(min(cfg.exposure_menu_s)), exposure_menu_s=())
    return coverage_upper_bound(dataclasses.replace(problem, config=shortest))


def make_plan(
    skymap: SkyMap,
    config: PlanningConfig = PlanningConfig(),
    start: Time | None = None,
    solver: str | None = None,
    event: EventInfo | None = None,
    supersedes: str | None = None,
    should_stop: StopCheck | None = None,
    times_before: Mapping[str, float] | None = None,
) -> Plan:
    """Plan ZTF follow-up of a sky map and check the plan.

    Parameters
    ----------
    skymap : SkyMap
        Sky map at ``config.nside``.
    config : PlanningConfig
        Planning parameters.
    start : astropy.time.Time, optional
        Horizon start; defaults to the merger time.
    solver : str, optional
        ``greedy``, ``slots``, ``blocks`` (alias ``milp``) or ``hybrid``;
        defaults to ``config.solver``.
    event : EventInfo, optional
        The alert being answered (goes into the plan document); its
        ``event_time`` (the notice's merger time) is the kilonova's clock,
        else the sky map's header (:func:`~.clock.on_merger_clock`).
    supersedes : str, optional
        plan_id of the plan this one replaces.
    should_stop : callable, optional
        Polled by the schedulers; True stops them early (the plan then holds
        what was found so far).
    times_before : mapping of str to float, optional
        Wall times (s) the caller spent before, e.g. ``{"load": 2.1}``: they
        open the one log line of stage times (:func:`stage_times_line`).

    Returns
    -------
    Plan
        A plan that passed :func:`~.checker.check_plan`.

    Raises
    ------
    InputError
        No start time, or an unknown solver.
    PlanCheckError
        The plan failed the checker (a scheduler bug; never published).

    Examples
    --------
    A greedy plan of the packaged map for the night of 2019-05-01 (at its
    own merger time the map is too close to the Sun):

    >>> from importlib.resources import files
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> from astropy.time import Time
    >>> from mushrooms.scheduler_core import PlanningConfig, read_skymap
    >>> config = PlanningConfig(solver="greedy", nside=64)
    >>> skymap = read_skymap(path, nside=config.nside)
    >>> plan = make_plan(skymap, config, start=Time("2019-05-01T03:00:00", scale="utc"))
    >>> plan.metrics.solver, plan.metrics.coverage > 0.9
    ('greedy', True)
    >>> sorted({o.filter for o in plan.observations})  # every field in both filters
    ['g', 'r']
    >>> doc = plan.to_document()
    >>> doc["type"], doc["plan_id"] == plan.plan_id
    ('plan', True)
    """
    t0 = time.perf_counter()
    solver = solver or config.solver
    if solver not in SOLVERS:
        raise InputError(unknown_solver_message(solver))
    skymap, event = on_merger_clock(skymap, event)  # the notice's merger time, else the map's
    if start is None:
        if skymap.event_time is None:
            raise InputError("the sky map has no event time (DATE-OBS); give a start time")
        start = skymap.event_time
    start = Time(start, scale="utc")
    problem = prepare_problem(skymap, config, start)
    t_prep = time.perf_counter() - t0
    t_opt = time.perf_counter()
    result = optimise(problem, skymap, solver, should_stop)
    t_build = time.perf_counter()
    plan = build_plan(problem, result, skymap, solver, event=event, supersedes=supersedes,
                      runtime_s=time.perf_counter() - t0)
    metrics = plan.metrics
    t_check = time.perf_counter()
    report = check_plan(plan, skymap, config)
    t_end = time.perf_counter()
    stages = result.details.get("stage_times_s") or {result.solver: result.runtime_s}
    optimised = t_build - t_opt
    times = {**(times_before or {}), "prepare": t_prep, **stages,
             "other": max(optimised - sum(stages.values()), 0.0),  # a scheduler's own wrapping, the menu bound
             "build": t_check - t_build, "checker": t_end - t_check}
    log.info("%s", stage_times_line(times))
    log.info("plan %s: %s %s, %d fields, %d exposures, coverage %.4f (checker %.4f), prepare %.1f s, total %.1f s",
             plan.plan_id, result.solver, result.status, metrics.n_fields, metrics.n_exposures,
             metrics.coverage, report.coverage, t_prep, time.perf_counter() - t0)
    if not report.ok:
        raise PlanCheckError(list(report.problems))
    return plan


def stage_times_line(times: Mapping[str, float]) -> str:
    """One log line of wall times (s): ``times: load 2.1 s, prepare 0.6 s, greedy 0.3 s, ..., total 9.8 s``.

    Stages under 5 ms are left out; ``total`` is the sum of all.
    """
    shown = ", ".join(f"{name} {s:.2f} s" for name, s in times.items() if s >= 0.005)
    return f"times: {shown}, total {sum(times.values()):.2f} s"


def build_plan(
    problem: PlanningProblem,
    result: ScheduleResult,
    skymap: SkyMap,
    solver: str,
    event: EventInfo | None = None,
    supersedes: str | None = None,
    runtime_s: float | None = None,
    keep_fields: Collection[int] = (),
) -> Plan:
    """Turn a scheduler's result into a :class:`Plan` (not checked here).

    Applies the least-gain rule (:func:`~.gain.drop_low_gain`) to every
    scheduler's result, and fills in each observation's airmass and field
    probability, the event time and sky-map name, and the configuration.

    Parameters
    ----------
    problem : PlanningProblem
        The problem the scheduler solved (config, start, footprints).
    result : ScheduleResult
        The scheduler's output.
    skymap : SkyMap
        The sky map (its hash keys the plan id).
    solver : str
        The scheduler asked for (``greedy``, ``slots``, ``blocks``, ``hybrid``).
    event : EventInfo, optional
        The alert answered.
    supersedes : str, optional
        plan_id of the plan replaced.
    runtime_s : float, optional
        Wall time to report (default: the scheduler's own).
    keep_fields : collection of int
        Fields the least-gain rule keeps whatever they add (a re-plan's
        later visits of covered fields, F3).

    Returns
    -------
    Plan
        Its plan_id depends only on the sky map, start, configuration,
        solver and superevent: the same inputs give the same id.
    """
    config = problem.config
    start = problem.start
    result = drop_low_gain(result, problem.footprints, problem.prob, config.min_gain, keep_fields)  # every scheduler
    if result.dropped_low_gain:
        log.info("least gain %.2g: dropped %d field(s) adding less", config.min_gain, len(result.dropped_low_gain))
    skymap, event = on_merger_clock(skymap, event)  # the same clock for the document and its detections
    event = with_map_details(event, skymap)
    observations = _with_airmass_and_probability(sorted_observations(result.observations), problem)
    ids = {o.field_id for o in observations}
    bound = result.mip_bound
    upper = None if result.upper_bound is None else result.upper_bound.value
    metrics = PlanMetrics(
        coverage=round(problem.footprints.coverage(ids, skymap.prob), 6),
        solver=result.solver,
        status=result.status,
        mip_gap=None if result.mip_gap is None else float(result.mip_gap),
        mip_bound=None if bound is None else round(float(bound), 6),
        runtime_s=round(result.runtime_s if runtime_s is None else runtime_s, 3),
        n_fields=len(ids),
        n_exposures=len(observations),
        upper_bound=None if upper is None else round(float(upper), 6),
        upper_bound_method=None if result.upper_bound is None else result.upper_bound.method,
        budget=result.details.get("budget"),
    )
    plan_id = make_plan_id(
        skymap.sha256, iso_utc(start), config.record(), solver, event.superevent_id,
    )
    plan = Plan(
        plan_id=plan_id,
        start=start,
        end=start + TimeDelta(config.horizon_s, format="sec"),
        observations=observations,
        metrics=metrics,
        event=event,
        supersedes=supersedes,
        config=json.loads(json.dumps(config.record())),  # JSON types (tuples become lists)
        telescope=telescope_label(config),
    )
    # the executor model (docs/design/executed.md) is ZTF's ToO queue: no executed coverage for another telescope
    modelled = observations and config.telescope == "ztf"
    executed, whole = _coverage_as_executed(plan, problem, result) if modelled else (None, None)
    return plan.with_(metrics=dataclasses.replace(
        metrics, expected_detections=_expected_detections(plan, problem, skymap, result),
        coverage_as_executed=None if executed is None else round(executed, 6),
        sequence_coverage_as_executed=None if whole is None else round(whole, 6)))


def telescope_label(config: PlanningConfig) -> str:
    """The document's ``telescope``: ``ZTF`` as always, another telescope's name in capitals (``LS4``)."""
    from .instruments.active import telescope_name

    return "ZTF" if config.telescope == "ztf" else telescope_name(config.telescope).upper()


def _coverage_as_executed(plan: Plan, problem: PlanningProblem, result: ScheduleResult) -> tuple[float, float]:
    """``metrics.coverage_as_executed`` and ``sequence_coverage_as_executed`` (Q14, Q21).

    For a pair the portfolio's value for this very plan when it has one (the
    two are equal), else one run of the executor for both.
    """
    if len(problem.config.filters) <= 2:
        memo = result.details.get(AS_EXECUTED_MEMO, {})
        known = memo.get(execution_key(problem, plan.observations)) if memo else None
        if known is not None:
            return float(known), float(known)
    pair, whole = queue_coverages(plan, problem.footprints, problem.prob)
    return pair, float(pair if whole is None else whole)


def _with_airmass_and_probability(observations: tuple[Observation, ...],
                                  problem: PlanningProblem) -> tuple[Observation, ...]:
    """Observations with their mid-exposure airmass, limiting magnitude (D2) and their field's probability."""
    if not observations:
        return observations
    from astropy import units as u
    from astropy.coordinates import AltAz, SkyCoord

    from .sky.visibility import site

    mid = problem.start + TimeDelta([o.start + o.exposure_s / 2 for o in observations], format="sec")
    coords = SkyCoord([o.ra for o in observations] * u.deg, [o.dec for o in observations] * u.deg)
    alt = coords.transform_to(AltAz(obstime=mid, location=site(problem.config.telescope))).alt.deg
    airmass = 1.0 / np.sin(np.radians(np.maximum(alt, 1e-3)))
    from .plan.shares import coverage_after_each, field_shares

    field_prob = dict(zip(problem.footprints.field_ids.tolist(),
                          problem.footprints.field_probability(problem.prob).tolist()))
    visits = [o.field_id for o in observations]
    shares = field_shares(problem.footprints, list(dict.fromkeys(visits)), problem.prob)
    after = coverage_after_each(problem.footprints, visits, problem.prob)
    from .source.detection import exposure_depths

    depth = exposure_depths(observations, problem.start, depth_model(problem.config))
    return tuple(dataclasses.replace(o, airmass=float(x), probability=field_prob.get(o.field_id),
                                     probability_share=shares[o.field_id], coverage_after=float(c),
                                     limiting_mag=float(m) if np.isfinite(m) else None)
                 for o, x, c, m in zip(observations, airmass, after, depth))


def _expected_detections(plan: Plan, problem: PlanningProblem, skymap: SkyMap,
                         result: ScheduleResult | None = None) -> float | None:
    """metrics.expected_detections for the configured light curve (None without distance layers).

    The detection stage's own score of the plan it returns (the same
    equation X1 on the same exposures, after the least-gain rule) is reused
    when it was made for the configured light curve.
    """
    from .source.detection import expected_detections
    from .source.kilonova import load_kilonova

    if not skymap.has_distance or skymap.event_time is None:
        return None
    if (result is not None and result.expected_detections is not None
            and result.expected_detections_lightcurve == problem.config.detection_lightcurve):
        return round(float(result.expected_detections), 6)
    e = expected_detections(plan, skymap, problem.footprints, load_kilonova(problem.config.detection_lightcurve),
                            depth=depth_model(problem.config))
    return None if e is None else round(e, 6)
