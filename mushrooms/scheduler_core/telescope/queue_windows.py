"""Validity windows that make ZTF's scheduler follow a plan pass by pass (Q11-Q13, Q20, ``docs/design/executed.md``).

A plan goes to ZTF as one timed ToO list queue per filter pass.  The
scheduler starts a pass as soon as its window opens and runs it as fast as
it can (Q1-Q3), so the windows, not idle waits, must hold the cadence.  They
are set pass by pass, in plan order, with the executor model itself
(:func:`.executor.execute_queues`, ztf_sim's rules):

* (Q11) pass k opens at its planned start, or later when the model says a
  field of the pass was visited (in another filter) too recently::

      open_k = max(s_k, max_j (t1_j + cadence + margin - (s_j - s_k)))

  with ``s_j`` a target's planned start, ``t1_j`` the modelled time of its
  field's earlier exposure in another filter (the model run on passes
  1..k-1 to the plan's end); then, every visit of every pass -- the second
  of a pair and the third of a g-r-g alike -- is checked in the model's run
  of the whole set: a visit less than ``cadence + margin`` after its
  field's previous one (the pass reached it sooner than planned) moves its
  pass's opening later by the shortfall, and the windows are timed again;
* (Q12) pass k closes ``slack`` after the model's end of the pass (at its
  opening when the model observes nothing of it): a pass whose fields have
  set does not keep the telescope from the next one, and a late telescope
  skips what it can no longer do on time instead of pushing the whole night;
* (Q13) a pass that cannot open before the plan's end is not exported;
* (Q20, :mod:`.order_free`) no switch of the on-time run has two queues to
  take, so first-wins and last-wins (Q1) run it the same;
* (Q16-Q18, :mod:`.late_windows`) given ``robust``, each close is then the
  wide one or a tight one, whichever keeps more pairs when the telescope
  starts late or runs faster or slower than modelled, as ztf_sim switches
  queues and then as a first-wins scheduler would (the on-time run is left
  as it is).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from astropy.time import Time

from .executor import ExecutedTarget, QueueSet, SkyGrid, execute_queues
from .late_windows import robust_closes
from .order_free import order_free_windows
from .timing import TelescopeTiming

__all__ = ["time_pass_windows", "CADENCE_MARGIN_S", "PASS_SLACK_S", "MAX_RETIMES"]

#: Extra separation (s) the windows keep beyond the cadence (a telescope faster than modelled).
CADENCE_MARGIN_S = 120.0
#: How long (s) a pass's queue stays open after the model's end of the pass.
PASS_SLACK_S = 1800.0
#: Most times the windows are timed again for a visit that came too soon (Q11).
MAX_RETIMES = 6


def time_pass_windows(qs: QueueSet, epoch: Time, planned_s: np.ndarray, end_s: float, cadence_s: float,
                      margin_s: float = CADENCE_MARGIN_S, slack_s: float = PASS_SLACK_S,
                      timing: TelescopeTiming = TelescopeTiming(), sky: SkyGrid | None = None,
                      weight: np.ndarray | None = None, robust: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Open and close times (s since ``epoch``) of each pass's queue (Q11-Q13, Q20; Q16-Q18 when ``robust``).

    Parameters
    ----------
    qs : QueueSet
        One queue per pass, in plan order (its windows are ignored).
    epoch : astropy.time.Time
        Time zero.
    planned_s : numpy.ndarray
        (n,) each target's planned start (s since ``epoch``).
    end_s : float
        The plan's end (s since ``epoch``).
    cadence_s, margin_s, slack_s : float
        Least separation of a field's consecutive visits, the margin beyond
        it and the close slack (s).
    timing : TelescopeTiming
        The telescope model (and the scheduler's rules).
    sky : SkyGrid, optional
        Observability grid of ``qs``'s targets (built when missing).
    weight : numpy.ndarray, optional
        (n,) each target's field weight: what a switch's choice keeps (Q20)
        and, with ``robust``, what a close keeps late or off-speed (Q17);
        default 1 each.
    robust : bool, optional
        Choose the closes for a late or off-speed telescope (Q16-Q18); the
        on-time execution is the same either way.  Default: when ``weight``
        is given.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        (K,) opens and closes; a pass not exported (Q13) has ``open = inf``.
    """
    robust = weight is not None if robust is None else robust
    weight = np.ones(len(qs)) if weight is None else np.asarray(weight, float)
    first = float(np.min(planned_s))
    if sky is None:
        sky = SkyGrid(qs, epoch, first, end_s, 60.0, timing)
    floors = np.full(len(qs.names), -math.inf)
    timed = None
    for _ in range(MAX_RETIMES):
        timed = _timed(qs, epoch, planned_s, end_s, cadence_s + margin_s, slack_s, timing, sky, floors, timed)
        opens, closes = order_free_windows(qs, epoch, timed[0], timed[1], first, end_s, weight, cadence_s, timing,
                                           sky)
        short = _too_soon(qs, _play(qs, epoch, opens, closes, first, end_s, timing, sky), cadence_s + margin_s)
        if not short:
            break
        for k, (started, shortfall) in short.items():
            floors[k] = max(floors[k], started) + shortfall
    if robust:
        closes = robust_closes(qs, epoch, opens, closes, weight, end_s, cadence_s, timing, sky)
    return opens, closes


def _timed(qs, epoch, planned_s, end_s, separation_s, slack_s, timing, sky, floors, before=None):
    """(Q11-Q13) each pass's open (at least its floor) and wide close, pass by pass in plan order.

    ``before``: the result of an earlier call with ``floors`` lower from some pass on, which depends only on
    the passes before it: those are kept, and the passes are timed again from the first raised floor.
    """
    k_total = len(qs.names)
    first = float(np.min(planned_s))
    opens, closes = np.full(k_total, math.inf), np.full(k_total, math.inf)
    start = 0
    if before is not None:
        opens, closes, used = before[0].copy(), before[1].copy(), before[2]
        raised = np.flatnonzero(floors != used)
        start = int(raised[0]) if raised.size else k_total
        opens[start:], closes[start:] = math.inf, math.inf
    for k in range(start, k_total):
        rows = np.flatnonzero(qs.queue == k)
        s_k = float(planned_s[rows].min())
        need = _cadence_open(qs, epoch, opens, closes, rows, planned_s, s_k, end_s, separation_s, timing, sky, k)
        open_k = max(s_k, need, floors[k])
        if not open_k < end_s:  # (Q13)
            continue
        opens[k], closes[k] = open_k, end_s
        done = _play(qs, epoch, opens, closes, first, end_s, timing, sky)
        ends = [d.start_s + d.exposure_s for d in done if qs.queue[d.target] == k and d.status == "processed"]
        closes[k] = min(end_s, (max(ends) if ends else open_k) + slack_s)
    return opens, closes, floors.copy()


def _play(qs, epoch, opens, closes, start_s, end_s, timing, sky) -> tuple[ExecutedTarget, ...]:
    trial = replace(qs, window_start_s=opens.copy(), window_end_s=np.where(np.isfinite(opens), closes, -math.inf))
    return execute_queues(trial, epoch, start_s, end_s, timing, sky=sky)


def _cadence_open(qs, epoch, opens, closes, rows, planned_s, s_k, end_s, separation_s, timing, sky, k) -> float:
    """(Q11) the earliest opening of pass ``k`` that keeps each of its fields ``separation_s`` after its other filter."""
    if k == 0 or not np.isfinite(opens[:k]).any():
        return -math.inf
    earlier = np.isin(qs.queue, np.flatnonzero(np.isfinite(opens[:k])))
    if not np.isin(qs.field_id[earlier], qs.field_id[rows]).any():
        return -math.inf  # no field of this pass in an exported pass before it: nothing to wait for
    done = _play(qs, epoch, opens, closes, float(np.min(planned_s)), end_s, timing, sky)
    need = -math.inf
    for d in done:
        if d.status != "processed":
            continue
        same = rows[(qs.field_id[rows] == qs.field_id[d.target]) & (qs.filter_id[rows] != qs.filter_id[d.target])]
        for j in same:
            need = max(need, d.start_s + separation_s - (float(planned_s[j]) - s_k))
    return need


def _too_soon(qs: QueueSet, done: tuple[ExecutedTarget, ...], separation_s: float) -> dict[int, tuple[float, float]]:
    """(Q11) passes with a visit less than ``separation_s`` after its field's previous visit in another filter.

    Returns
    -------
    dict of int to (float, float)
        Pass -> (start of its first exposure in the run, the largest shortfall (s)).
    """
    out: dict[int, tuple[float, float]] = {}
    first: dict[int, float] = {}
    seen: dict[int, list[tuple[float, int]]] = {}
    for d in sorted((d for d in done if d.status == "processed"), key=lambda d: d.start_s):
        k, field, band = int(qs.queue[d.target]), int(qs.field_id[d.target]), int(qs.filter_id[d.target])
        first.setdefault(k, d.start_s)
        earlier = [t for t, b in seen.get(field, []) if b != band]
        if earlier and d.start_s - max(earlier) < separation_s - 1e-6:
            shortfall = separation_s - (d.start_s - max(earlier))
            out[k] = (first[k], max(shortfall, out.get(k, (0.0, 0.0))[1]))
        seen.setdefault(field, []).append((d.start_s, band))
    return out
