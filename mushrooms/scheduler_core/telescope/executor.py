"""How ZTF's scheduler carries out a set of ToO list queues (equations Q1-Q10, ``docs/design/executed.md``).

Follows ztf_sim's main loop (``ZwickyTransientFacility/ztf_sim``, commit
c5ab409, BSD-3-Clause licence; read, not copied; file and line of each fact
in :mod:`.rules` and ``docs/design/executed.md``):

* ``simulate.py`` calls ``Scheduler.check_for_timed_queue_and_switch``: a
  queue whose validity window has closed hands the telescope back to the
  default (survey) queue; from the default queue the scheduler switches to
  the **last** queue, in the order the queues were added, whose window holds
  *now* and which still has targets (Q1; ``timing.rules.switch``).  The
  exposure itself may run past the window's end: only the moment of choice
  is checked.
* ``ListQueueManager._next_obs``: the first target in list order that passes
  *now* -- airmass below its ``max_airmass`` (default ``MAX_AIRMASS`` 2.5;
  ztf_sim's airmass is negative below the horizon, so a set target passes),
  |HA| < 5.95 h, the mount's keep-out zones for southern declinations,
  Dec <= 87.5 deg (:func:`~..sky.constraints.mount_limits_ok`) -- the ones
  passed over stay queued (Q2); ``QueueEmptyError`` when none passes.  A
  target that passes but whose slew ``slew_allowed`` refuses (below 10 deg)
  holds the queue: the telescope waits 30 s and tries it again.
* ``simulate.py``: on ``QueueEmptyError`` (none passes) the scheduler falls
  back to the default queue, whose survey observes meanwhile (one exposure,
  ``survey_step_s``) and the ToO pointing is lost (Q3); the next choice
  starts again from Q1.  An emptied queue is left at once by default (a
  survey exposure first with ``rules.emptied = "survey"``, as
  ``simulate.py`` does).  Nothing is observed
  with the Sun above 12 deg below the horizon
  (``TelescopeStateMachine.can_observe``, Q9).
* ``TelescopeStateMachine``: filter change, then slew (Q7,
  :func:`.timing.exposure_overhead_s`), then the exposure; the request leaves
  the queue once the exposure completed (``_remove_requests``).

Observability is evaluated on a grid (``grid_s``, default 60 s) of the sky's
geometry (:func:`~..sky.constraints.observing_geometry`), nearest grid time.
Times are seconds since an epoch (e.g. the plan's start).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from astropy.time import Time, TimeDelta

from ..executed import ExecutedExposure
from ..sky.constraints import mount_limits_ok, observing_geometry
from ..sky.visibility import site
from .timing import TelescopeTiming, dome_azimuth_deg, exposure_overhead_s

__all__ = ["QueueSet", "ExecutedTarget", "SkyGrid", "queue_set_from_payloads", "execute_queues", "executed_exposures",
           "first_switch_conflict", "FILTER_NAMES", "SIDEREAL_DEG_S"]

#: ZTF queue filter ids to names.
FILTER_NAMES = {1: "g", 2: "r", 3: "i"}
#: Sidereal rate (deg of hour angle per s of UTC).
SIDEREAL_DEG_S = 360.98564736629 / 86400.0
#: ztf_sim ``slew_allowed``: no slew below 10 deg of altitude (airmass above 1 / sin 10 deg) ...
SLEW_MAX_AIRMASS = 1.0 / math.sin(math.radians(10.0))
#: ... nor south of Dec -35 deg.
SLEW_MIN_DEC_DEG = -35.0


@dataclass(frozen=True)
class QueueSet:
    """ToO list queues in submission order, their targets in one table (list order within a queue).

    Attributes
    ----------
    names : tuple of str
        Queue names, in the order the scheduler received them.
    window_start_s, window_end_s : numpy.ndarray
        (K,) validity windows (s since the epoch).
    queue : numpy.ndarray
        (n,) index of each target's queue; targets of one queue are contiguous, in list order.
    field_id, filter_id : numpy.ndarray
        (n,) ZTF field and filter ids (1 g, 2 r, 3 i).
    ra, dec, exposure_s, max_airmass : numpy.ndarray
        (n,) pointing (deg), exposure time (s) and the target's airmass limit.
    """

    names: tuple[str, ...]
    window_start_s: np.ndarray
    window_end_s: np.ndarray
    queue: np.ndarray
    field_id: np.ndarray
    filter_id: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    exposure_s: np.ndarray
    max_airmass: np.ndarray

    def __len__(self) -> int:
        return int(self.queue.size)


@dataclass(frozen=True)
class ExecutedTarget:
    """One exposure the executor took (or started) of a queue target.

    Attributes
    ----------
    target : int
        Row in the :class:`QueueSet`.
    start_s, exposure_s : float
        Shutter open (s since the epoch) and how long it stayed open (s).
    status : str
        ``processed``, or ``aborted`` when a dome closure cut it short.
    """

    target: int
    start_s: float
    exposure_s: float
    status: str


def queue_set_from_payloads(payloads: Sequence[Mapping[str, Any]], epoch: Time,
                            timing: TelescopeTiming = TelescopeTiming()) -> QueueSet:
    """The queues as submitted (``to_trigger_queues`` payloads, in submission order) as a :class:`QueueSet`.

    A queue without ``validity_window_mjd`` is valid throughout.
    """
    names, ws, we, rows = [], [], [], []
    for k, p in enumerate(payloads):
        names.append(str(p["queue_name"]))
        window = p.get("validity_window_mjd")
        if window is None:
            ws.append(-math.inf), we.append(math.inf)
        else:
            ws.append(float((Time(window[0], format="mjd") - epoch).to_value("s")))
            we.append(float((Time(window[1], format="mjd") - epoch).to_value("s")))
        for t in p["targets"]:
            rows.append((k, int(t["field_id"]), int(t["filter_id"]), float(t["ra"]), float(t["dec"]),
                         float(t.get("exposure_time", 30.0)), float(t.get("max_airmass", timing.max_airmass))))
    table = np.array(rows, dtype=float).reshape(-1, 7)
    return QueueSet(names=tuple(names), window_start_s=np.array(ws), window_end_s=np.array(we),
                    queue=table[:, 0].astype(int), field_id=table[:, 1].astype(int),
                    filter_id=table[:, 2].astype(int), ra=table[:, 3], dec=table[:, 4], exposure_s=table[:, 5],
                    max_airmass=table[:, 6])


class SkyGrid:
    """Observability of a queue set's targets and the Sun's altitude on a time grid (Q2, Q9).

    Built once per target table; any windows of the same targets reuse it.
    """

    def __init__(self, qs: QueueSet, epoch: Time, t0: float, t1: float, grid_s: float, timing: TelescopeTiming):
        self.t0, self.grid_s = t0, grid_s
        offsets = t0 + grid_s * np.arange(int(math.ceil((t1 - t0) / grid_s)) + 2)
        times = epoch + TimeDelta(offsets, format="sec")
        geo = observing_geometry(qs.ra, qs.dec, times, site())
        self.ha = geo.ha_deg  # (n, m)
        self.observable, self.refused = _checks(geo.airmass, geo.ha_deg, qs.dec, qs.max_airmass, timing)
        self.dark = geo.sun_alt_deg < timing.sun_alt_max_deg
        self.offsets = offsets
        self.limits = _limits(timing)
        self.overheads: dict[tuple, float] = {}  # (Q7) memo: runs of one set repeat the same moves

    def serves(self, start_s: float, timing: TelescopeTiming) -> bool:
        """True when a run starting at ``start_s`` under ``timing`` samples this very grid.

        The grid's times are ``t0 + k grid_s``, so a run from another start would
        see other samples; ``timing`` must have the limits the grid was made with.
        """
        return start_s == self.t0 and _limits(timing) == self.limits

    def take(self, rows: np.ndarray) -> "SkyGrid":
        """The grid of the targets ``rows`` (in that order): a queue set made of some of these targets."""
        out = object.__new__(SkyGrid)
        out.__dict__.update(self.__dict__, ha=self.ha[rows], observable=self.observable[rows],
                            refused=self.refused[rows], overheads={})
        return out

    def index(self, t: float) -> int:
        return int(min(max(round((t - self.t0) / self.grid_s), 0), self.offsets.size - 1))

    def hour_angle(self, rows: np.ndarray | int, t: float) -> np.ndarray:
        j = self.index(t)
        return self.ha[rows, j] + (t - self.offsets[j]) * SIDEREAL_DEG_S

    def next_dark(self, t: float) -> float:
        later = np.flatnonzero(self.dark & (self.offsets > t))
        return float(self.offsets[later[0]]) if later.size else math.inf


def _checks(airmass: np.ndarray, ha_deg: np.ndarray, dec: np.ndarray, max_airmass: np.ndarray,
            timing: TelescopeTiming) -> tuple[np.ndarray, np.ndarray]:
    """(Q2) which targets ``_next_obs`` takes and is then slewed to (observable), and which it takes but
    whose slew is refused (refused), each (n, m).

    ztf_sim's airmass is ``1 / cos(zenith angle)``: negative below the horizon, so a target that has set
    passes ``airmass < max_airmass`` (``airmass`` here is ``inf`` there).  ``slew_allowed`` then wants
    an altitude of at least 10 deg and Dec >= -35 deg.
    """
    below = ~np.isfinite(airmass)
    taken = ((airmass < max_airmass[:, None]) | below) & mount_limits_ok(ha_deg, dec[:, None], timing.ha_max_h)
    slews = (airmass <= SLEW_MAX_AIRMASS) & (dec[:, None] >= SLEW_MIN_DEC_DEG)
    return taken & slews, taken & ~slews


def _limits(timing: TelescopeTiming) -> tuple[float, float, float]:
    """What of the telescope a :class:`SkyGrid` depends on: airmass, hour-angle and Sun limits."""
    return timing.max_airmass, timing.ha_max_h, timing.sun_alt_max_deg


def _closure(spans: Sequence[tuple[float, float]], t0: float, t1: float) -> tuple[float, float] | None:
    """The first closure overlapping ``[t0, t1)`` (``t0 == t1``: the one ``t0`` is in)."""
    for cs, ce in spans:
        if cs <= t0 < ce or (cs < t1 and ce > t0):
            return cs, ce
    return None


def execute_queues(qs: QueueSet, epoch: Time, start_s: float, end_s: float,
                   timing: TelescopeTiming = TelescopeTiming(), closures_s: Sequence[tuple[float, float]] = (),
                   grid_s: float = 60.0, sky: "SkyGrid | None" = None) -> tuple[ExecutedTarget, ...]:
    """Play the queues from ``start_s`` (the telescope free) until ``end_s`` (Q1-Q10).

    Parameters
    ----------
    qs : QueueSet
        The queues, in submission order.
    epoch : astropy.time.Time
        Time zero of every time here.
    start_s, end_s : float
        When the telescope becomes free for the queues (a late start is a
        later ``start_s``) and when the run stops (s since ``epoch``).
    timing : TelescopeTiming
        Overheads and limits (a faster/slower telescope: :meth:`TelescopeTiming.scaled`),
        and the scheduler's rules (``timing.rules``: which open queue is taken,
        a refused slew, an emptied queue; :mod:`.rules`).
    closures_s : sequence of (float, float)
        Dome closures (s since ``epoch``): nothing runs inside; an exposure
        one cuts is ``aborted`` and its target stays queued (Q10).
    grid_s : float
        Step (s) of the observability grid.
    sky : SkyGrid, optional
        A grid already built for these targets (covering ``start_s`` to ``end_s``).

    Returns
    -------
    tuple of ExecutedTarget
        In execution order.
    """
    if len(qs) == 0 or not end_s > start_s:
        return ()
    return tuple(_play(qs, epoch, start_s, end_s, timing, closures_s, grid_s, sky, stop_at_conflict=False).out)


def first_switch_conflict(qs: QueueSet, epoch: Time, start_s: float, end_s: float,
                          timing: TelescopeTiming = TelescopeTiming(), sky: "SkyGrid | None" = None
                          ) -> tuple[float, tuple[int, ...]] | None:
    """(Q20) the first time the run (as :func:`execute_queues`) leaves the default queue with a choice.

    Returns
    -------
    (float, tuple of int) or None
        The time (s since ``epoch``) and the queues, in submission order, open
        and not empty at that switch; None when every switch of the run has
        one queue to take: then the first and the last valid queue are the
        same one at every switch, and the run is the same under either rule (Q1).
    """
    if len(qs) == 0 or not end_s > start_s:
        return None
    night = _play(qs, epoch, start_s, end_s, timing, (), 60.0, sky, stop_at_conflict=True)
    return night.conflicts[0] if night.conflicts else None


def _play(qs: QueueSet, epoch: Time, start_s: float, end_s: float, timing: TelescopeTiming,
          closures_s: Sequence[tuple[float, float]], grid_s: float, sky: "SkyGrid | None",
          stop_at_conflict: bool) -> "_Night":
    if sky is None:
        hi = min(end_s, float(np.max(qs.window_end_s)))
        sky = SkyGrid(qs, epoch, start_s, max(hi, start_s + grid_s), grid_s, timing)
    night = _Night(qs, sky, timing, sorted(closures_s), float(start_s), float(end_s))
    while night.t < end_s and night.alive.any() and night.step():
        if stop_at_conflict and night.conflicts:
            break
    return night


class _Night:
    """The state of one run of the queues: time, current queue, pointing, filter, targets left (Q1-Q10)."""

    def __init__(self, qs: QueueSet, sky: SkyGrid, timing: TelescopeTiming, spans: list[tuple[float, float]],
                 start_s: float, end_s: float):
        self.qs, self.sky, self.timing, self.rules, self.spans = qs, sky, timing, timing.rules, spans
        self.end_s, self.t = end_s, start_s
        self.alive = np.ones(len(qs), bool)
        self.last_filter: int | None = None
        self.pointing: tuple[int, float] | None = None  # (target row, end of its exposure)
        self.current = -1
        self.switched = False  # the current queue was taken from the default queue at this choice
        self.out: list[ExecutedTarget] = []
        self.conflicts: list[tuple[float, tuple[int, ...]]] = []  # switches with more than one queue to take

    def step(self) -> bool:
        """One choice of the scheduler at ``t``; False when nothing more can happen before ``end_s``."""
        closed = _closure(self.spans, self.t, self.t)
        if closed is not None:  # (Q10) the dome is shut
            self.t, self.pointing = closed[1], None
            return True
        if not self.sky.dark[self.sky.index(self.t)]:  # (Q9) the Sun is up: on to the next night
            self.t, self.pointing = self.sky.next_dark(self.t), None
            return True
        chosen = self._queue()
        if chosen is None:
            return True
        if chosen < 0:
            return False
        return self._target(chosen)

    def _survey(self) -> None:
        """(Q3) the survey takes one exposure; where the telescope then points is unknown (Q8)."""
        self.current, self.pointing = -1, None
        self.t += self.timing.survey_step_s

    def _queue(self) -> int | None:
        """(Q1) the queue to play now: its index, None when the survey took the time, -1 when none will open."""
        qs, t = self.qs, self.t
        self.switched = False
        left = np.bincount(qs.queue[self.alive], minlength=len(qs.names))
        open_now = (qs.window_start_s <= t) & (t <= qs.window_end_s)
        if self.current >= 0 and not open_now[self.current]:
            self.current = -1  # (Q1) its window closed: back to the default queue
        if self.current >= 0 and left[self.current] == 0:
            if self.rules.emptied == "survey":  # (Q3) QueueEmptyError: the survey's exposure, then Q1
                self._survey()
                return None
            self.current = -1
        if self.current < 0:
            ks = np.flatnonzero(open_now & (left > 0))
            if ks.size == 0:  # (Q3) no queue open: the survey has the telescope until one opens
                later = qs.window_start_s[(qs.window_start_s > t) & (left > 0) & (qs.window_start_s < self.end_s)]
                if later.size == 0:
                    return -1
                steps = max(1, math.ceil((float(later.min()) - t) / self.timing.survey_step_s))
                self.t, self.pointing = t + self.timing.survey_step_s * steps, None
                return None
            if ks.size > 1:
                self.conflicts.append((t, tuple(int(k) for k in ks)))
            self.current = int(ks[-1] if self.rules.switch == "last" else ks[0])
            self.switched = True
        return self.current

    def _target(self, k: int) -> bool:
        """(Q2) the first target of queue ``k`` in list order that passes the checks now: observe or retry it."""
        sky, j = self.sky, self.sky.index(self.t)
        rows = np.flatnonzero(self.alive & (self.qs.queue == k))  # contiguous: list order
        ok = sky.observable[rows, j]
        if self.rules.refused == "retry":
            ok = ok | sky.refused[rows, j]
        if not ok.any():  # (Q3) nothing passes now: the survey takes one exposure, the pointing is lost
            # the same choice comes back at every survey step until a window, the sky or the Sun changes
            n = self._idle_steps(k, rows, self.timing.survey_step_s, every_queue=True) if self.switched else 1
            self._survey()
            self.t += self.timing.survey_step_s * (n - 1)
            return True
        i = int(rows[np.argmax(ok)])
        if not sky.observable[i, j]:
            self._retry(i, rows)
        else:
            self._observe(i)
        return True

    def _retry(self, i: int, rows: np.ndarray) -> None:
        """(Q2) a refused slew: the filter is changed all the same, then the telescope waits and chooses again.

        It chooses the same target again, and waits again, until its queue's window closes or the sky or the
        Sun changes: those waits are taken at once (the same times as one by one).
        """
        if self.last_filter is not None and self.last_filter != int(self.qs.filter_id[i]):
            self.t += self.timing.filter_change_s
            self.last_filter = int(self.qs.filter_id[i])
            self.t += self.rules.retry_s
            return
        self.last_filter = int(self.qs.filter_id[i])
        self.t += self.rules.retry_s * self._idle_steps(int(self.qs.queue[i]), rows, self.rules.retry_s,
                                                         every_queue=False)  # it has not moved: the pointing stays

    def _idle_steps(self, k: int, rows: np.ndarray, step_s: float, every_queue: bool) -> int:
        """How many choices, ``step_s`` apart from ``t``, make the very choice made at ``t`` (at least 1).

        Nothing is observed meanwhile, so the choice changes only when a window opens or closes (any queue's
        when ``every_queue``: the scheduler switches again at each step; else queue ``k``'s), when the grid
        column of queue ``k``'s targets ``rows`` or the Sun's state changes, at a closure, or at the end.
        """
        qs, sky, t = self.qs, self.sky, self.t
        if every_queue:
            live = np.bincount(qs.queue[self.alive], minlength=len(qs.names)) > 0
            opens, closes = qs.window_start_s[live], qs.window_end_s[live]
        else:
            opens, closes = qs.window_start_s[k:k + 1], qs.window_end_s[k:k + 1]
        events = [self.end_s, *opens[opens > t], *np.nextafter(closes[closes >= t], math.inf)]
        events += [cs for cs, _ in self.spans if cs > t]
        event = min(events)
        n = max(1, math.ceil((event - t) / step_s))
        j = sky.index(t)
        now = np.concatenate([sky.observable[rows, j], sky.refused[rows, j], [sky.dark[j]]])
        later = np.vstack([sky.observable[rows, j + 1:], sky.refused[rows, j + 1:], sky.dark[None, j + 1:]])
        changed = np.flatnonzero((later != now[:, None]).any(axis=0))
        if changed.size:
            first = j + 1 + int(changed[0])  # the first grid column that differs
            while n > 1 and sky.index(t + (n - 1) * step_s) >= first:
                n -= 1
        return n

    def _observe(self, i: int) -> None:
        """Filter change, slew, exposure (Q7); a closure cuts it (Q10)."""
        qs, t = self.qs, self.t
        t0 = t + _overhead(self.sky, qs, self.pointing, self.last_filter, i, t, self.timing)
        t1 = t0 + float(qs.exposure_s[i])
        closed = _closure(self.spans, t, t1)
        if closed is not None:
            if closed[0] > t0:
                self.out.append(ExecutedTarget(i, t0, closed[0] - t0, "aborted"))
            self.t, self.pointing = closed[1], None
            return
        self.out.append(ExecutedTarget(i, t0, float(qs.exposure_s[i]), "processed"))
        self.alive[i] = False
        self.t, self.pointing, self.last_filter = t1, (i, t1), int(qs.filter_id[i])


def _overhead(sky: SkyGrid, qs: QueueSet, pointing: tuple[int, float] | None, last_filter: int | None, i: int,
              t: float, timing: TelescopeTiming) -> float:
    """(Q7) filter change, then the slew from the previous pointing (Q8: a lost pointing costs a mean slew)."""
    change = last_filter is not None and last_filter != int(qs.filter_id[i])
    t_slew = t + (timing.filter_change_s if change else 0.0)
    if pointing is None:
        # (Q8) the pointing was lost: a mean slew of lost_pointing_slew_s
        return (timing.filter_change_s if change else 0.0) + max(timing.lost_pointing_slew_s,
                                                                  timing.slew.readout_s)
    p, p_end = pointing
    key = (p, p_end, i, t_slew, change, timing.slew, timing.filter_change_s, timing.dome_accel_deg_s2,
           timing.dome_vmax_deg_s)
    known = sky.overheads.get(key)
    if known is None:
        ha1, ha2 = float(sky.hour_angle(p, p_end)), float(sky.hour_angle(i, t_slew))
        known = sky.overheads[key] = float(exposure_overhead_s(
            ha1, qs.dec[p], dome_azimuth_deg(ha1, qs.dec[p]), ha2, qs.dec[i], dome_azimuth_deg(ha2, qs.dec[i]),
            change, timing))
    return known


def executed_exposures(qs: QueueSet, done: Sequence[ExecutedTarget], epoch: Time) -> tuple[ExecutedExposure, ...]:
    """The executor's exposures as :class:`~..executed.ExecutedExposure` records (absolute times)."""
    if not done:
        return ()
    starts = epoch + TimeDelta(np.array([d.start_s for d in done]), format="sec")
    return tuple(
        ExecutedExposure(field_id=int(qs.field_id[d.target]), filter=FILTER_NAMES[int(qs.filter_id[d.target])],
                         start=starts[k], exposure_s=float(d.exposure_s),
                         processed_fraction=1.0 if d.status == "processed" else 0.0, status=d.status)
        for k, d in enumerate(done))
