"""Loop benchmark, executor half: how ZTF's list queue would carry out a published plan.

A plan goes to ZTF as a *list* queue (:func:`~mushrooms.scheduler_core.plan.exports.to_trigger_queue`):
its observations in plan order, no planned times, valid over the plan's
horizon.  :func:`execute_plan` plays that queue against the observability
windows, the telescope's overheads and weather closures, and returns what
was executed as :class:`~mushrooms.scheduler_core.executed.ExecutedExposure`
records, the same the readers of :mod:`mushrooms.handlers.executed` return
for the real telescope.  :func:`achieved_coverage` scores them.  The model,
equations (Q1)-(Q6), is in ``docs/design/executed.md``.

The queue's behaviour follows ztf_sim (``ZwickyTransientFacility/ztf_sim``,
commit c5ab409, BSD-3-Clause licence), read, not copied:
``ztf_sim/QueueManager.py`` ``ListQueueManager._next_obs`` returns the first
request in list order that is observable *now* (airmass, hour angle and
mount limits), leaving the ones it passes over in the queue, and raises
``QueueEmptyError`` when none is; ``_remove_requests`` drops a request only
after its exposure completed; ``ztf_sim/Scheduler.py`` deletes a timed queue
once its validity window has ended; ``ztf_sim/simulate.py`` waits one
exposure time (``TelescopeStateMachine.wait``) when nothing can be observed
and forgets the previous pointing then.  Here "observable now" is the
project's own window test (the planner's windows: Sun, airmass, hour angle,
Moon, declination), and the overheads are the planner's slew model
(:func:`~mushrooms.scheduler_core.schedulers.slew.overhead_time`).

Pure functions, no I/O; times inside are seconds since the plan's start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
from astropy.time import Time, TimeDelta

from ..scheduler_core.config import PlanningConfig
from ..scheduler_core.executed import MIN_PROCESSED_FRACTION, ExecutedExposure, done_pairs
from ..scheduler_core.plan.document import Observation, Plan
from ..scheduler_core.schedulers.slew import overhead_time
from ..scheduler_core.sky.footprints import Footprints
from ..scheduler_core.sky.skymap import SkyMap
from ..scheduler_core.sky.windows import Windows

__all__ = ["Closure", "random_closure", "execute_plan", "achieved_coverage", "IDLE_STEP_S"]

#: What the telescope does while the list queue has nothing observable: one
#: exposure of another queue (ztf_sim waits ``EXPOSURE_TIME`` = 30 s), then asks again.
IDLE_STEP_S = 30.0


@dataclass(frozen=True)
class Closure:
    """The dome closed for weather from ``start`` to ``end`` (UTC).

    Attributes
    ----------
    start, end : astropy.time.Time
        Closure span, ``start < end``.
    """

    start: Time
    end: Time

    def __post_init__(self) -> None:
        if not (isinstance(self.start, Time) and isinstance(self.end, Time)):
            raise TypeError("Closure start and end are astropy Times")
        if not self.start < self.end:
            raise ValueError(f"closure must end after it starts ({self.start.isot} .. {self.end.isot})")

    @property
    def duration_s(self) -> float:
        """Length of the closure (s)."""
        return float((self.end - self.start).to_value("s"))


def random_closure(night_start: Time, night_end: Time, seed: int | np.random.Generator,
                   min_h: float = 1.0, max_h: float = 3.0) -> Closure:
    """A weather closure of random length at a random time inside a night.

    Parameters
    ----------
    night_start, night_end : astropy.time.Time
        The night (UTC), e.g. the span of the plan's windows.
    seed : int or numpy.random.Generator
        Same seed, same closure.
    min_h, max_h : float
        Closure length (h), uniform in ``[min_h, max_h]``, cut to the night's length.

    Returns
    -------
    Closure
        Lies inside ``[night_start, night_end]``; start uniform over the
        times that leave room for the length drawn.
    """
    night_s = float((night_end - night_start).to_value("s"))
    if not night_s > 0:
        raise ValueError("the night must end after it starts")
    if not 0 < min_h <= max_h:
        raise ValueError(f"need 0 < min_h <= max_h, got {min_h}, {max_h}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    length = min(rng.uniform(min_h, max_h) * 3600.0, night_s)
    offset = rng.uniform(0.0, night_s - length)
    start = night_start + TimeDelta(offset, format="sec")
    return Closure(start, start + TimeDelta(length, format="sec"))


class _FieldWindows:
    """Per-field windows (s since the plan start) in time order, for the queue's questions."""

    def __init__(self, windows: Windows):
        self._by_field: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        order = np.lexsort((windows.start, windows.field_ids))
        ids = np.asarray(windows.field_ids)[order]
        starts = np.asarray(windows.start, float)[order]
        ends = np.asarray(windows.end, float)[order]
        for f in np.unique(ids):
            sel = ids == f
            self._by_field[int(f)] = (starts[sel], ends[sel])

    def fits(self, field_id: int, t0: float, t1: float) -> bool:
        """(Q1) ``[t0, t1]`` inside one window of the field."""
        s, e = self._by_field.get(field_id, (np.zeros(0), np.zeros(0)))
        return bool(np.any((s <= t0) & (t1 <= e)))

    def next_opening(self, field_id: int, t: float) -> float:
        """The first window start after ``t`` (s), inf when none."""
        s, _ = self._by_field.get(field_id, (np.zeros(0), np.zeros(0)))
        later = s[s > t]
        return float(later[0]) if later.size else math.inf


def _overhead(prev: Observation | None, nxt: Observation, config: PlanningConfig) -> float:
    """(Q5) the gap before an exposure: the slew model's overhead from the previous pointing;
    the planner's mean ``slew_estimate_s`` after an idle spell or at the start (pointing unknown)."""
    if prev is None:
        return float(config.slew_estimate_s)
    change = config.filter_change_s if prev.filter != nxt.filter else 0.0
    return float(overhead_time(prev.ra, prev.dec, nxt.ra, nxt.dec, config.slew, change))


def _closure_at(spans: Sequence[tuple[float, float]], t: float) -> tuple[float, float] | None:
    for cs, ce in spans:
        if cs <= t < ce:
            return cs, ce
    return None


def _closure_during(spans: Sequence[tuple[float, float]], t: float, t1: float) -> tuple[float, float] | None:
    for cs, ce in spans:
        if cs < t1 and ce > t:
            return cs, ce
    return None


def execute_plan(plan: Plan, windows: Windows, config: PlanningConfig = PlanningConfig(), start: Time | None = None,
                 closures: Iterable[Closure] = (), idle_step_s: float = IDLE_STEP_S,
                 keep_planned_times: bool = False) -> tuple[ExecutedExposure, ...]:
    """What ZTF's list queue executes of a plan (equations Q1-Q5 of ``docs/design/executed.md``).

    From ``start`` the telescope repeatedly takes the first observation, in
    plan order, whose exposure fits one of its field's windows once the
    overhead from the previous exposure has passed (Q1) and ends within the
    queue's validity, the plan's horizon (Q2); observations passed over stay
    in the queue.  When none fits it idles (another program observes) in
    steps of ``idle_step_s`` until a window opens (Q3).  A closed dome stops
    everything until the closure ends; an exposure the closure starts in is
    recorded ``aborted`` (fraction 0) and stays in the queue (Q4).  Each
    completed exposure is ``processed`` with fraction 1 and leaves the queue.

    Parameters
    ----------
    plan : Plan
        The published plan (its observations in the order sent).
    windows : Windows
        Observability windows of the plan's fields, s since ``plan.start``
        (e.g. the planning problem's); a field without any is never observed.
    config : PlanningConfig
        Slew model, filter change and the overhead assumed after an idle
        spell (``slew_estimate_s``).
    start : astropy.time.Time, optional
        When the queue starts running (default ``plan.start``; earlier is
        taken as ``plan.start``).
    closures : iterable of Closure
        Weather closures.
    idle_step_s : float
        Idle step (s) when nothing in the queue is observable.
    keep_planned_times : bool
        Also refuse an observation before its planned start (a timed queue,
        keeping the plan's waits for the cadence).  ZTF's list queue does
        not: False.

    Returns
    -------
    tuple of ExecutedExposure
        In execution order, aborted attempts included.
    """
    if not idle_step_s > 0:
        raise ValueError(f"idle_step_s must be > 0, got {idle_step_s}")
    t_end = float((plan.end - plan.start).to_value("s"))
    t = 0.0 if start is None else max(0.0, float((start - plan.start).to_value("s")))
    spans = sorted((float((c.start - plan.start).to_value("s")), float((c.end - plan.start).to_value("s")))
                   for c in closures)
    fw = _FieldWindows(windows)
    queue = list(plan.observations)
    prev: Observation | None = None
    done: list[tuple[Observation, float, float, str]] = []  # (observation, start, length, status)
    while queue and t < t_end:
        closed = _closure_at(spans, t)
        if closed is not None:  # (Q4) the dome is shut: nothing until it opens
            t, prev = closed[1], None
            continue
        pick = None
        for k, o in enumerate(queue):
            t0 = t + _overhead(prev, o, config)
            if keep_planned_times and t0 < o.start:
                continue
            # (Q2) the queue is valid over the plan's horizon only
            if t0 + o.exposure_s > t_end:
                continue
            # (Q1) the first observation, in list order, whose exposure fits a window now
            if fw.fits(o.field_id, t0, t0 + o.exposure_s):
                pick = (k, o, t0)
                break
        if pick is None:
            # (Q3) idle in steps until a window (or, timed, a planned start) opens
            nxt = min(min((fw.next_opening(o.field_id, t) for o in queue), default=math.inf),
                      min((o.start for o in queue if keep_planned_times and o.start > t), default=math.inf))
            if not nxt < t_end:
                break
            t, prev = t + idle_step_s * max(1, math.ceil((nxt - t) / idle_step_s)), None
            continue
        k, o, t0 = pick
        t1 = t0 + o.exposure_s
        closed = _closure_during(spans, t, t1)
        if closed is not None:
            cs, ce = closed
            if cs > t0:  # (Q4) shut during the exposure: lost, the request stays queued
                done.append((o, t0, cs - t0, "aborted"))
            t, prev = ce, None
            continue
        done.append((o, t0, o.exposure_s, "processed"))
        del queue[k]
        t, prev = t1, o  # (Q5) the next exposure starts after this one ends and the overhead
    if not done:
        return ()
    starts = plan.start + TimeDelta(np.array([d[1] for d in done]), format="sec")
    return tuple(
        ExecutedExposure(field_id=o.field_id, filter=o.filter, start=starts[i], exposure_s=float(length),
                         processed_fraction=1.0 if status == "processed" else 0.0, status=status)
        for i, (o, _, length, status) in enumerate(done)
    )


def achieved_coverage(executed: Iterable[ExecutedExposure], skymap: SkyMap, footprints: Footprints,
                      filters: tuple[str, str] = ("g", "r"), require: str = "both",
                      min_processed_fraction: float = MIN_PROCESSED_FRACTION, cadence_s: float = 0.0) -> float:
    """Probability inside the footprints of the fields observed (Q6).

    The plan's own ``metrics.coverage`` counts each planned field, and a
    plan visits each field in both filters; ``require="both"`` counts a field
    on the same terms (done in both filters (E3), at least ``cadence_s``
    apart), ``"any"`` once one done exposure (E1) in either filter exists.
    The union is taken by :meth:`Footprints.coverage`, as the bench does.

    Parameters
    ----------
    executed : iterable of ExecutedExposure
        What was executed (any source).
    skymap : SkyMap
        The sky map, at ``footprints.nside``.
    footprints : Footprints
        Footprints of (at least) the executed fields.
    filters : tuple of str
        The plan's two filters.
    require : str
        ``both`` or ``any``.
    min_processed_fraction : float
        Threshold of the done rule (E1).
    cadence_s : float
        Least separation (s) of a field's two filters with ``require="both"``.

    Returns
    -------
    float
        Coverage (0-1).
    """
    if require not in ("both", "any"):
        raise ValueError(f"require must be 'both' or 'any', got {require!r}")
    if skymap.nside != footprints.nside:
        raise ValueError(f"sky map nside {skymap.nside} differs from the footprints' {footprints.nside}")
    pairs = done_pairs(executed, filters, min_processed_fraction, cadence_s)
    ids = set(pairs.both) | (set(pairs.one) if require == "any" else set())
    known = set(int(f) for f in footprints.field_ids)
    missing = sorted(ids - known)
    if missing:
        raise ValueError(f"field(s) {missing[:5]} not in the footprints")
    return footprints.coverage(sorted(ids), skymap.prob) if ids else 0.0
