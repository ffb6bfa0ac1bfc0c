"""Loop benchmark, one sky map: the list queue alone against the daemon's re-plan after a closure.

Night 1 (its validity window, :func:`~mushrooms.scheduler_core.sky.twilight.night_windows`,
N1) is planned once; a weather closure falls in it.  Two arms, both played
by the same executor (:func:`~.queue_sim.execute_plan`: the plan's queues as ZTF runs them, Q1-Q13):

(a) *queue*: the original plan runs as ZTF's list queue would through the
    closure (what no longer fits is skipped, what expired is dropped);
(b) *loop*: the same until the closure starts; at the reopening the daemon
    re-plans (:func:`~mushrooms.scheduler_core.replan.plan_remaining`, start =
    reopening, executed = what (a)'s executor produced before the closure,
    horizon = the rest of the night as the daemon's L7), and the re-plan runs
    as the list queue from the reopening.

Each arm is scored by its achieved coverage (Q14: fields done in both
filters) and expected detections (X1, the plans' own metric, on the done
exposures).  Night 2 is then planned by ``plan_remaining`` on each arm's
executed record; its ``metrics.coverage`` is what the second night adds.
Equations (W1)-(W5): ``docs/design/executed.md``, section 5.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from astropy.time import Time

from ..scheduler_core.config import PlanningConfig
from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, ExecutedExposure, is_done
from ..scheduler_core.sequences import done_covering
from ..scheduler_core.plan.document import Observation, Plan
from ..scheduler_core.sky.fields import FieldGrid, field_footprints, load_ztf_fields
from ..scheduler_core.sky.footprints import Footprints
from ..scheduler_core.sky.skymap import SkyMap
from .queue_sim import Closure, achieved_coverage, execute_plan

__all__ = ["LoopArm", "LoopOutcome", "first_night", "loop_map", "executed_detections", "repeated_pairs"]


@dataclass(frozen=True)
class LoopArm:
    """What one arm executed and achieved on night 1, and what night 2 adds to it.

    Attributes
    ----------
    executed : tuple of ExecutedExposure
        Night 1's executed record (aborted attempts included).
    coverage : float
        Achieved coverage (Q14, pairs at any separation).
    coverage_cadence : float
        The same with the pair's two filters at least ``cadence_s`` apart.
    expected_detections : float or None
        (X1) of the done exposures; None without distance layers.
    night2_coverage : float or None
        What night 2's plan on this record adds (``metrics.coverage``); None when not asked.
    night2_coverage_executed : float or None
        What night 2's plan counts as done before it (``metrics.coverage_executed``: the
        pairs at least ``cadence_s`` apart, so ``coverage_cadence``); None when not asked.
        The coverage after two nights is ``coverage_cadence + night2_coverage``.
    """

    executed: tuple[ExecutedExposure, ...]
    coverage: float
    coverage_cadence: float
    expected_detections: float | None
    night2_coverage: float | None = None
    night2_coverage_executed: float | None = None

    @property
    def n_done(self) -> int:
        """Done exposures (E1)."""
        return sum(is_done(e) for e in self.executed)


@dataclass(frozen=True)
class LoopOutcome:
    """One map's two arms under one closure.

    Attributes
    ----------
    plan : Plan
        The original plan of night 1.
    closure : Closure
        The weather closure.
    queue : LoopArm
        Arm (a), the list queue alone.
    loop : LoopArm
        Arm (b), the daemon's re-plan at the reopening.
    replan : Plan or None
        The re-plan (None when the closure ends after the night or nothing was left).
    repeats : int
        Exposures of (b)'s re-plan in a field already done in both filters before the closure (0 by P1).
    clear : LoopArm or None
        The original plan through the list queue on a clear night (no closure, no night 2): what
        the queue alone loses without weather.
    """

    plan: Plan
    closure: Closure
    queue: LoopArm
    loop: LoopArm
    replan: Plan | None
    repeats: int
    clear: LoopArm | None = None


def first_night(start: Time, config: PlanningConfig) -> tuple[Time, Time]:
    """Night 1's validity window ``(evening, morning)`` from ``start`` (N1; a night under way starts at ``start``)."""
    from ..scheduler_core.sky.twilight import night_windows

    return night_windows(start, config, 1)[0]


def executed_detections(executed: Sequence[ExecutedExposure], plan: Plan, skymap: SkyMap, footprints: Footprints,
                        grid: FieldGrid, lightcurve: str,
                        min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> float | None:
    """Expected detections (X1) of the done exposures (E1) of an executed record.

    The record is scored as a plan of its done exposures at their executed
    times (field centres from the grid), with the plans' own metric
    (:func:`~mushrooms.scheduler_core.source.detection.expected_detections`):
    one detection suffices, so a field done in one filter counts too.

    Parameters
    ----------
    executed : sequence of ExecutedExposure
        The record.
    plan : Plan
        A plan of the map (its start is the time origin; its metadata is kept).
    skymap : SkyMap
        With distance layers and an event time (else None is returned).
    footprints : Footprints
        Of the grid at the map's resolution.
    grid : FieldGrid
        The field grid (centres).
    lightcurve : str
        Packaged light-curve name or file (``config.detection_lightcurve``).
    min_processed_fraction : float
        Done rule (E1).

    Returns
    -------
    float or None
        In [0, 1]; None without distance layers or event time.
    """
    from ..scheduler_core.source.detection import expected_detections
    from ..scheduler_core.source.kilonova import load_kilonova

    if not skymap.has_distance or skymap.event_time is None:
        return None
    done = [e for e in executed if is_done(e, min_processed_fraction)]
    if not done:
        return 0.0
    rows = grid.index_of(np.array([e.field_id for e in done], dtype=int))
    obs = tuple(Observation(field_id=e.field_id, ra=float(grid.ra[k]), dec=float(grid.dec[k]), filter=e.filter,
                            start=float((e.start - plan.start).to_value("s")), exposure_s=e.exposure_s, block=0)
                for e, k in zip(done, rows.tolist()))
    return expected_detections(plan.with_(observations=obs), skymap, footprints, load_kilonova(lightcurve))


def repeated_pairs(replan: Plan, before: Sequence[ExecutedExposure], config: PlanningConfig,
                   min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> int:
    """Exposures of ``replan`` in fields done in both filters (E3, ``config.cadence_s``) by ``before``."""
    both = set(done_covering(before, tuple(config.filters), min_processed_fraction, config.cadence_s).both)
    return sum(o.field_id in both for o in replan.observations)


def _arm(executed: tuple[ExecutedExposure, ...], plan: Plan, skymap: SkyMap, config: PlanningConfig,
         footprints: Footprints, grid: FieldGrid) -> LoopArm:
    """(W4) an arm's scores: coverage (Q14) at any separation and at the cadence, expected detections (X1)."""
    filters = tuple(config.filters)
    return LoopArm(executed=executed,
                   coverage=achieved_coverage(executed, skymap, footprints, filters),
                   coverage_cadence=achieved_coverage(executed, skymap, footprints, filters,
                                                      cadence_s=config.cadence_s),
                   expected_detections=executed_detections(executed, plan, skymap, footprints, grid,
                                                           config.detection_lightcurve))


def _night2(arm: LoopArm, skymap: SkyMap, config: PlanningConfig, start: Time, solver: str,
            grid: FieldGrid) -> LoopArm:
    """(W5) night 2 planned on the arm's night-1 record (N2): what it adds."""
    from ..scheduler_core.replan import plan_remaining
    from ..scheduler_core.sky.twilight import night_windows

    evening, morning = night_windows(start, config, 2)[1]
    night = dataclasses.replace(config, horizon_h=float((morning - evening).to_value("h")))
    plan = plan_remaining(skymap, night, evening, arm.executed, solver=solver, grid=grid)
    return dataclasses.replace(arm, night2_coverage=float(plan.metrics.coverage),
                               night2_coverage_executed=float(plan.metrics.coverage_executed))


def loop_map(skymap: SkyMap, config: PlanningConfig, start: Time, closure: Closure | int, *,
             solver: str = "greedy", second_night: bool = True, grid: FieldGrid | None = None,
             footprints: Footprints | None = None) -> LoopOutcome:
    """Both arms of the loop benchmark on one sky map.

    Parameters
    ----------
    skymap : SkyMap
        At ``config.nside``.
    config : PlanningConfig
        Planning parameters (``horizon_h`` is replaced by night 1's length).
    start : astropy.time.Time
        From when (UTC): night 1 is the first night at or after it.
    closure : Closure or int
        The weather closure, or a seed for
        :func:`~.queue_sim.random_closure` over night 1's window (1-3 h).
    solver : str
        Scheduler of the original plan and of every re-plan.
    second_night : bool
        Also plan night 2 on each arm's record.
    grid : FieldGrid, optional
        Field grid (default all ZTF fields).
    footprints : Footprints, optional
        Of ``grid`` at ``config.nside`` (computed when not given).

    Returns
    -------
    LoopOutcome

    Raises
    ------
    ValueError
        The original plan observes nothing (nothing to benchmark).
    """
    from ..scheduler_core.planner import build_plan, optimise
    from ..scheduler_core.prepare import prepare_problem
    from ..scheduler_core.replan import plan_remaining
    from .queue_sim import random_closure

    grid = grid if grid is not None else load_ztf_fields()
    footprints = footprints if footprints is not None else field_footprints(grid, config.nside)
    # (W1) night 1's window, the original plan over it, the closure in it
    evening, morning = first_night(start, config)
    night = dataclasses.replace(config, horizon_h=float((morning - evening).to_value("h")))
    problem = prepare_problem(skymap, night, evening, grid=grid, footprints=footprints)
    plan = build_plan(problem, optimise(problem, skymap, solver), skymap, solver)
    if not plan.observations:
        raise ValueError("the original plan observes nothing")
    if not isinstance(closure, Closure):
        closure = random_closure(evening, morning, closure)
    # (W2) arm (a): the list queue alone, through the closure
    executed_a = execute_plan(plan, closures=[closure])
    queue = _arm(executed_a, plan, skymap, night, footprints, grid)
    # (W3) arm (b): the same until the closure, then the daemon's re-plan from the reopening (L6, L7)
    before = tuple(e for e in executed_a if e.start < closure.start)
    left_h = float((plan.end - closure.end).to_value("h"))
    replan, executed_b, repeats = None, before, 0
    if left_h > 0:
        rest = dataclasses.replace(night, horizon_h=min(night.horizon_h, max(1.0, left_h)))
        replan = plan_remaining(skymap, rest, closure.end, before, solver=solver, grid=grid,
                                supersedes=plan.plan_id)
        if replan.observations:
            executed_b = before + execute_plan(replan, closures=[closure])
        repeats = repeated_pairs(replan, before, night)
    loop = _arm(executed_b, plan, skymap, night, footprints, grid)
    if second_night:
        queue = _night2(queue, skymap, config, start, solver, grid)
        loop = _night2(loop, skymap, config, start, solver, grid)
    clear = _arm(execute_plan(plan), plan, skymap, night, footprints, grid)
    return LoopOutcome(plan=plan, closure=closure, queue=queue, loop=loop, replan=replan, repeats=repeats,
                       clear=clear)
