"""Re-planning from now, given what the telescope did: :func:`plan_remaining`.

The executed record (:mod:`.executed`) says which fields are done in both
filters (they count as covered: their pixels' probability is not counted
again, P1) and which in one (their other filter is still worth an exposure
at least the cadence after the first, P2).  The re-plan is

1. the completion pass (P4, :func:`~.schedulers.completions.completion_pass`):
   the half-done fields that are due, from the start;
2. the rest of the horizon planned by any scheduler of the registry on the
   *reduced problem*: the sky map with the covered pixels (executed pairs
   and the pass's fields) set to zero, starting after the pass and one
   worst-case overhead (so the schedulers, which do not know the pass's
   last pointing, cannot start too early);
3. the completions that were not due yet fitted into that plan's gaps (P7).

With a filter sequence other than a pair (``docs/design/sequences.md``,
F3) the half-done fields are the covered ones whose sequence is not
finished: their next visit is pending whatever it adds, kept by the
least-gain rule, and made room for by delaying what follows it when no gap
takes it; a field with done visits but not covered is planned anew.

Metrics (P8): ``coverage`` is what the plan *adds* (probability inside the
fields it completes or observes, outside the executed pairs);
``coverage_executed`` what the executed pairs already hold; the total is
their sum.  The plan goes through :func:`~.plan.checker.check_plan` with the
executed record, which checks the same.  Equations: ``docs/design/replan.md``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import time
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from astropy.time import Time, TimeDelta

from .config import PlanningConfig
from .errors import InputError, PlanCheckError
from .executed import MIN_PROCESSED_FRACTION, DonePairs, ExecutedExposure, to_record
from .plan.checker import check_plan
from .plan.document import EventInfo, Observation, Plan, iso_utc, make_plan_id
from .problem import PlanningProblem, ScheduleResult, StopCheck
from .schedulers.completions import (
    PendingVisit, completion_pass, drop_repeats, insert_completions, shift_in_completions, swap_in_completions,
)
from .schedulers.gain import worth_a_visit
from .telescope.mount import altaz_mount
from .telescope.slew import overhead_time
from .sequences import done_covering, is_pair, sequence_progress
from .sky.fields import FieldGrid, field_footprints
from .sky.footprints import Footprints
from .sky.skymap import SkyMap
from .plan.localization import with_map_details
from .prepare import telescope_grid_and_camera
from .sky.visibility import observability_windows
from .sky.windows import Windows

__all__ = ["plan_remaining", "ExecutedState", "executed_state"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ExecutedState:
    """What an executed record means for a plan starting at ``start`` (P1, P2).

    Attributes
    ----------
    pairs : DonePairs
        :func:`~.sequences.done_covering` with the plan's filters and cadence
        (:func:`~.executed.done_pairs` of the pair, or of a sequence's first two, F1).
    covered : numpy.ndarray
        Sorted IDs of the grid fields done in both filters.
    uncovered : numpy.ndarray
        The sky map's probability with the covered fields' pixels set to 0 (P1).
    coverage_executed : float
        Probability inside the covered fields' union.
    pending : tuple of PendingVisit
        The half-done fields' missing exposures (P2), in field order.
    unknown : tuple of int
        Executed field IDs not on the grid (ignored).
    """

    pairs: DonePairs
    covered: np.ndarray
    uncovered: np.ndarray
    coverage_executed: float
    pending: tuple[PendingVisit, ...]
    unknown: tuple[int, ...]


def executed_state(skymap: SkyMap, config: PlanningConfig, start: Time,
                   executed: Sequence[ExecutedExposure], footprints: Footprints, grid: FieldGrid,
                   min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> ExecutedState:
    """Covered fields, remaining probability and pending visits (P1, P2).

    Parameters
    ----------
    skymap : SkyMap
        At ``config.nside``.
    config : PlanningConfig
        Filters and cadence.
    start : astropy.time.Time
        The re-plan's start (UTC).
    executed : sequence of ExecutedExposure
        The record (any order, duplicates allowed; only done exposures, E1, count).
    footprints : Footprints
        Of the whole grid, in grid order.
    grid : FieldGrid
        The field grid.
    min_processed_fraction : float
        The done rule's threshold (E1).

    Returns
    -------
    ExecutedState
    """
    pairs = done_covering(executed, tuple(config.filters), min_processed_fraction, config.cadence_s,
                          config.pair_separation_s)
    rows = grid.index_of(np.array(sorted(set(pairs.both) | set(pairs.one)), dtype=int))
    known = set(grid.ids[rows[rows >= 0]].tolist())
    unknown = tuple(sorted((set(pairs.both) | set(pairs.one)) - known))
    if unknown:
        log.warning("executed record: field(s) %s are not on the %s grid; ignored", ", ".join(map(str, unknown)),
                    config.telescope)
    covered = np.array(sorted(set(pairs.both) & known), dtype=int)
    # (P1) the executed pairs' pixels are covered: their probability is not counted again
    uncovered = skymap.prob.copy()
    covered_pixels = footprints.union(covered)
    coverage_executed = float(skymap.prob[covered_pixels].sum())
    uncovered[covered_pixels] = 0.0
    if not is_pair(config.filters):  # (F3) a covered field's next visit; the others are planned anew
        pending = _sequence_pending(skymap, config, start, executed, footprints, grid, covered,
                                    min_processed_fraction)
        return ExecutedState(pairs, covered, uncovered, coverage_executed, pending, unknown)
    pending = []
    for field_id in sorted(set(pairs.one) & known):
        visits = pairs.one[field_id]
        if float((start - visits.earliest).to_value("s")) > config.pair_separation_s:
            continue  # (P10) its other filter can no longer make a pair with it: planned as a new pair
        first = visits.filters[0]
        other = config.filters[1] if first == config.filters[0] else config.filters[0]
        k = int(grid.index_of(np.array([field_id]))[0])
        # (P2) the other filter at least the cadence after the first done exposure, never before the start
        due = max(0.0, float((visits.first[first] - start).to_value("s")) + config.cadence_s)
        latest = float((visits.first[first] - start).to_value("s")) + config.pair_separation_s  # (P10)
        pending.append(PendingVisit(field_id, float(grid.ra[k]), float(grid.dec[k]), other, due, latest))
    return ExecutedState(pairs, covered, uncovered, coverage_executed, tuple(pending), unknown)


def _sequence_pending(skymap: SkyMap, config: PlanningConfig, start: Time, executed: Sequence[ExecutedExposure],
                      footprints: Footprints, grid: FieldGrid, covered: np.ndarray,
                      min_processed_fraction: float) -> tuple[PendingVisit, ...]:
    """(F3) The next visit of each covered field that has not finished its sequence.

    Due a cadence after its last counted visit (F2), never before the start;
    no later than the pair separation after its first.  It adds no coverage:
    its worth is the field's probability (at least ``min_gain``), so the
    re-plan keeps it before new fields.  A field two or more visits short
    (sequences of four or more) gets its next visit only, and a warning.
    """
    progress = sequence_progress(executed, tuple(config.filters), min_processed_fraction, config.cadence_s,
                                 config.pair_separation_s)
    seq, out, short = tuple(config.filters), [], []
    for field_id in covered.tolist():
        p = progress.get(int(field_id))
        if p is None or p.done >= len(seq):
            continue
        if len(seq) - p.done > 1:
            short.append(int(field_id))
        k = int(grid.index_of(np.array([field_id]))[0])
        worth = max(float(skymap.prob[footprints.pixels(int(field_id))].sum()), config.min_gain, 1e-12)
        due = max(0.0, float((p.last - start).to_value("s")) + config.cadence_s)
        latest = float((p.first - start).to_value("s")) + config.pair_separation_s
        out.append(PendingVisit(int(field_id), float(grid.ra[k]), float(grid.dec[k]), seq[p.done], due, latest,
                                worth))
    if short:
        log.warning("executed record: field(s) %s are two or more visits short of the sequence %s; only the next "
                    "visit is planned", ", ".join(map(str, short)), "-".join(seq))
    return tuple(out)


def plan_remaining(skymap: SkyMap, config: PlanningConfig, start: Time,
                   executed: Sequence[ExecutedExposure], *, event: EventInfo | None = None,
                   min_processed_fraction: float = MIN_PROCESSED_FRACTION, solver: str | None = None,
                   should_stop: StopCheck | None = None, grid: FieldGrid | None = None,
                   supersedes: str | None = None) -> Plan:
    """Plan the rest of the horizon from ``start`` given the executed exposures.

    Fields done in both filters (E3, with ``config.cadence_s``) count as
    covered and are not observed again; a field done in one filter gets its
    other filter at least the cadence after the first and inside a window,
    when that adds at least ``config.min_gain`` (P3); the rest of the time
    goes to the scheduler ``solver`` on the remaining probability.

    Parameters
    ----------
    skymap : SkyMap
        Sky map at ``config.nside``.
    config : PlanningConfig
        Planning parameters (the plan covers ``[start, start + horizon]``).
    start : astropy.time.Time
        When the telescope can start (now, or the reopening), UTC.
    executed : sequence of ExecutedExposure
        What was observed (failed, aborted and partial exposures, below
        ``min_processed_fraction``, do not count).
    event : EventInfo, optional
        The alert answered.
    min_processed_fraction : float
        Done rule (E1), default 0.5.
    solver : str, optional
        Scheduler name (default ``config.solver``).
    should_stop : callable, optional
        Polled by the scheduler.
    grid : FieldGrid, optional
        The field grid (default the telescope's: all ZTF fields for ZTF).
    supersedes : str, optional
        plan_id of the plan this one replaces.

    Returns
    -------
    Plan
        Checked (:func:`~.plan.checker.check_plan` with the executed
        record): every exposure at or after ``start``; ``metrics.coverage``
        what the plan adds, ``metrics.coverage_executed`` what the executed
        pairs hold.

    Raises
    ------
    InputError
        An unknown solver, or a sky map at another resolution.
    PlanCheckError
        The plan failed the checker (a bug; never published).
    """
    from .clock import on_merger_clock
    from .planner import SOLVERS
    from .solvers_registry import unknown_solver_message

    t0 = time.perf_counter()
    solver = solver or config.solver
    if solver not in SOLVERS:
        raise InputError(unknown_solver_message(solver))
    if skymap.nside != config.nside:
        raise InputError(f"sky map nside {skymap.nside} differs from config nside {config.nside}")
    start = Time(start, scale="utc")
    skymap, event = on_merger_clock(skymap, event)
    # the telescope's own grid and detectors (ZTF: its grid and 16 CCDs), as its first plan's
    grid, camera = telescope_grid_and_camera(config, None, grid)
    footprints = field_footprints(grid, config.nside, camera)
    state = executed_state(skymap, config, start, executed, footprints, grid, min_processed_fraction)
    sel, windows = _candidates(state, config, start, grid, footprints)
    observations, result = _schedule(skymap, config, start, grid, footprints, state, sel, windows, solver,
                                     should_stop)
    plan = _build(skymap, config, start, grid, footprints, windows, state, result, observations,
                  solver, event, supersedes, executed, time.perf_counter() - t0)
    report = check_plan(plan, skymap, config, executed=executed, min_processed_fraction=min_processed_fraction)
    _log_replan(plan, start, state, report.coverage, time.perf_counter() - t0)
    if not report.ok:
        raise PlanCheckError(list(report.problems))
    return plan


def _log_replan(plan: Plan, start: Time, state: ExecutedState, checked: float, wall_s: float) -> None:
    """One line: what the executed pairs hold, what the re-plan completes and adds."""
    n_completed = len(set(plan.field_ids) & {v.field_id for v in state.pending})
    log.info("re-plan %s from %s: %d done pair(s) covered (%.4f), %d of %d half-done field(s) completed, "
             "%d fields, %d exposures, adds %.4f (checker %.4f), %.1f s",
             plan.plan_id, iso_utc(start), state.covered.size, state.coverage_executed, n_completed,
             len(state.pending), plan.metrics.n_fields, plan.metrics.n_exposures, plan.metrics.coverage,
             checked, wall_s)


def _candidates(state: ExecutedState, config: PlanningConfig, start: Time, grid: FieldGrid,
                footprints: Footprints) -> tuple[np.ndarray, Windows]:
    """The grid fields still worth a visit (in the band, not covered, P3) and their windows over the horizon."""
    in_band = (grid.dec >= config.dec_min_deg) & (grid.dec <= config.dec_max_deg)
    sel = in_band & worth_a_visit(footprints, state.uncovered, config.min_gain) & ~np.isin(grid.ids, state.covered)
    # (F3) the windows of a sequence's pending visits too (their fields are covered: no candidates)
    timed = sel | (in_band & np.isin(grid.ids, [v.field_id for v in state.pending if v.worth is not None]))
    return sel, observability_windows(grid.ids[timed], grid.ra[timed], grid.dec[timed], start, config)


def _schedule(skymap: SkyMap, config: PlanningConfig, start: Time, grid: FieldGrid, footprints: Footprints,
              state: ExecutedState, sel: np.ndarray, windows: Windows, solver: str,
              should_stop: StopCheck | None) -> tuple[tuple[Observation, ...], ScheduleResult]:
    """The re-plan's exposures (s since ``start``): the pass (P4), the reduced problem (P5), P6, P7."""
    from .planner import optimise

    # (P4) the completion pass (F3: a covered field's next visit of a sequence is pending, not a candidate)
    pending = tuple(v for v in state.pending
                    if v.worth is not None or sel[int(grid.index_of(np.array([v.field_id]))[0])])
    front, later, uncovered = completion_pass(pending, footprints, state.uncovered, windows, config)
    # (P5) the reduced problem: after the pass and the worst first overhead, without covered fields
    rest_start = _rest_start(front, grid, sel, config, start)
    observations: list[Observation] = list(front)
    result = ScheduleResult((), solver="completions", status="no_time_left")
    if rest_start + 2 * config.exposure_s + config.cadence_s <= config.horizon_s:
        rest = _reduced_problem(skymap, config, start, rest_start, grid, footprints, windows, uncovered,
                                {o.field_id for o in front} | {v.field_id for v in pending if v.worth is not None})
        result = dataclasses.replace(result, status="nothing_left")
        if rest.field_ids.size:
            result = optimise(rest, dataclasses.replace(skymap, prob=uncovered), solver, should_stop)
            block0 = 1 if front else 0
            observations += [dataclasses.replace(o, start=o.start + rest_start, block=o.block + block0)
                             for o in result.observations]
    # (P6) a half-done field planned as a whole new pair: its done filter is not repeated
    trimmed_obs, trimmed = drop_repeats(observations, state.pending)
    if trimmed:
        log.info("re-plan: half-done field(s) %s were planned as whole pairs; their done filter is not repeated",
                 ", ".join(map(str, trimmed)))
    # (P7) the completions that were not due: into the gaps, else in the place of a field adding less
    covered_now = uncovered.copy()
    covered_now[footprints.union({o.field_id for o in trimmed_obs})] = 0.0
    placed, left = insert_completions(trimmed_obs, later, footprints, covered_now, windows, config)
    if left:
        completions = {v.field_id for v in state.pending} & {o.field_id for o in placed}
        placed, left = swap_in_completions(placed, left, footprints, state.uncovered, windows, config,
                                           keep=completions)
    if any(v.worth is not None for v in left):  # (F3) a sequence's next visits: delay what follows them
        placed, left = shift_in_completions(placed, left, windows, config, pending=state.pending)
    if left:
        log.info("re-plan: %d half-done field(s) found no time for their other filter: %s",
                 len(left), ", ".join(str(v.field_id) for v in left))
    return placed, result


def _rest_start(front: Sequence[Observation], grid: FieldGrid, sel: np.ndarray, config: PlanningConfig,
                start: Time) -> float:
    """When the reduced problem may start (s): after the pass, plus the longest overhead from its last exposure."""
    if not front:
        return 0.0
    last = front[-1]
    change = config.filter_change_s if last.filter != config.filters[0] else 0.0
    oh = overhead_time(last.ra, last.dec, grid.ra[sel], grid.dec[sel], config.slew, change,
                       altaz_mount(config, start), last.end)  # (M1)
    worst = float(np.max(oh)) if np.size(oh) else config.slew.readout_s
    return float(np.ceil(last.end + worst))


def _reduced_problem(skymap: SkyMap, config: PlanningConfig, start: Time, rest_start: float, grid: FieldGrid,
                     footprints: Footprints, windows: Windows, uncovered: np.ndarray,
                     pinned: set[int]) -> PlanningProblem:
    """The problem of the rest: from ``start + rest_start``, the covered pixels at 0, no covered or pinned field."""
    from .prepare import prepare_problem

    cfg = dataclasses.replace(config, horizon_h=(config.horizon_s - rest_start) / 3600.0)
    keep = ~np.isin(windows.field_ids, list(pinned))
    w0 = np.maximum(windows.start[keep] - rest_start, 0.0)
    w1 = windows.end[keep] - rest_start
    ok = w1 - w0 >= config.exposure_s
    shifted = Windows(windows.field_ids[keep][ok], w0[ok], w1[ok])
    return prepare_problem(dataclasses.replace(skymap, prob=uncovered), cfg,
                           start + TimeDelta(rest_start, format="sec"), grid=grid, footprints=footprints,
                           windows=shifted)


def _build(skymap: SkyMap, config: PlanningConfig, start: Time, grid: FieldGrid, footprints: Footprints,
           windows: Windows, state: ExecutedState, result: ScheduleResult, observations: Sequence[Observation],
           solver: str, event: EventInfo | None, supersedes: str | None,
           executed: Sequence[ExecutedExposure], runtime_s: float) -> Plan:
    """The plan document: metrics on the remaining probability (P8), an id that names the executed record.

    The scheduler's own scores (bounds, expected detections) are of the
    reduced problem, not of the whole plan: they are dropped, and the
    expected detections scored again on the plan's final exposures.
    """
    from .planner import build_plan

    ids = np.unique(np.concatenate([[o.field_id for o in observations], windows.field_ids]).astype(int))
    rows = grid.index_of(ids)
    problem = PlanningProblem(config=config, start=start, prob=state.uncovered, field_ids=ids,
                              ra=grid.ra[rows], dec=grid.dec[rows], footprints=footprints.subset(ids),
                              windows=windows)
    merged = dataclasses.replace(result, observations=tuple(observations), upper_bound=None, mip_bound=None,
                                 expected_detections=None, expected_detections_lightcurve=None)
    # (P8) on the remaining probability: what the plan adds (coverage, expected detections); the event's
    # areas and distance are the whole map's, as in the plan this one supersedes
    remaining = dataclasses.replace(skymap, prob=state.uncovered)
    event = with_map_details(event, skymap)
    plan = build_plan(problem, merged, remaining, solver, event=event, supersedes=supersedes, runtime_s=runtime_s,
                      keep_fields={v.field_id for v in state.pending if v.worth is not None})
    field_prob = dict(zip(ids.tolist(), footprints.subset(ids).field_probability(skymap.prob).tolist()))
    digest = hashlib.sha256(json.dumps(sorted(json.dumps(to_record(e), sort_keys=True) for e in executed))
                            .encode()).hexdigest()[:16]
    return plan.with_(
        plan_id=make_plan_id(skymap.sha256, iso_utc(start), dataclasses.asdict(config), solver,
                             plan.event.superevent_id, "executed", digest),
        observations=tuple(dataclasses.replace(o, probability=field_prob.get(o.field_id)) for o in plan.observations),
        metrics=dataclasses.replace(plan.metrics, coverage_executed=round(state.coverage_executed, 6)),
    )
