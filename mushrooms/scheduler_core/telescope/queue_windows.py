"""Validity windows that make ZTF's scheduler follow a plan pass by pass (Q11-Q13, ``docs/design/executed.md``).

A plan goes to ZTF as one timed ToO list queue per filter pass.  The
scheduler starts a pass as soon as its window opens and runs it as fast as
it can (Q1-Q3), so the windows, not idle waits, must hold the cadence.  They
are set pass by pass, in plan order, with the executor model itself
(:func:`.executor.execute_queues`):

* (Q11) pass k opens at its planned start, or later when the model says a
  field of the pass was first visited (in another filter) too recently::

      open_k = max(s_k, max_j (t1_j + cadence + margin - (s_j - s_k)))

  with ``s_j`` a target's planned start, ``t1_j`` the modelled time of its
  field's earlier exposure in another filter: the pass then reaches target
  j no sooner than a cadence (plus ``margin``, for a telescope a little
  faster than modelled) after that exposure;
* (Q12) pass k closes ``slack`` after the model's end of the pass (at its
  opening when the model observes nothing of it): a pass whose fields have
  set does not keep the telescope from the next one (the scheduler returns
  to the first open queue in submission order, Q1), and a late telescope
  skips what it can no longer do on time instead of pushing the whole night;
* (Q13) a pass that cannot open before the plan's end is not exported;
* (Q16-Q18, :mod:`.late_windows`) given the fields' weights, each close is
  then the wide one or a tight one, whichever keeps more pairs when the
  telescope starts late or runs faster or slower than modelled.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from astropy.time import Time

from .executor import QueueSet, SkyGrid, execute_queues
from .late_windows import robust_closes
from .timing import TelescopeTiming

__all__ = ["time_pass_windows", "CADENCE_MARGIN_S", "PASS_SLACK_S"]

#: Extra separation (s) the windows keep beyond the cadence (a telescope faster than modelled).
CADENCE_MARGIN_S = 120.0
#: How long (s) a pass's queue stays open after the model's end of the pass.
PASS_SLACK_S = 1800.0


def time_pass_windows(qs: QueueSet, epoch: Time, planned_s: np.ndarray, end_s: float, cadence_s: float,
                      margin_s: float = CADENCE_MARGIN_S, slack_s: float = PASS_SLACK_S,
                      timing: TelescopeTiming = TelescopeTiming(), sky: SkyGrid | None = None,
                      weight: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Open and close times (s since ``epoch``) of each pass's queue (Q11-Q13).

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
        Least separation of a field's two filters, the margin beyond it and
        the close slack (s).
    timing : TelescopeTiming
        The telescope model.
    sky : SkyGrid, optional
        Observability grid of ``qs``'s targets (built when missing).
    weight : numpy.ndarray, optional
        (n,) each target's field weight: when given, the closes are chosen
        for a late or off-speed telescope (Q16-Q18); the on-time execution
        is the same either way.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        (K,) opens and closes; a pass not exported (Q13) has ``open = inf``.
    """
    k_total = len(qs.names)
    first = float(np.min(planned_s))
    if sky is None:
        sky = SkyGrid(qs, epoch, first, end_s, 60.0, timing)
    opens, closes = np.full(k_total, math.inf), np.full(k_total, math.inf)
    for k in range(k_total):
        rows = np.flatnonzero(qs.queue == k)
        s_k = float(planned_s[rows].min())
        open_k = max(s_k, _cadence_open(qs, epoch, opens, closes, rows, planned_s, s_k, end_s, cadence_s + margin_s,
                                        timing, sky, k))
        if not open_k < end_s:  # (Q13)
            continue
        opens[k], closes[k] = open_k, end_s
        done = _run(qs, epoch, opens, closes, first, min(end_s, open_k + 4 * 3600.0), timing, sky)
        ends = [d.start_s + d.exposure_s for d in done if qs.queue[d.target] == k and d.status == "processed"]
        closes[k] = min(end_s, (max(ends) if ends else open_k) + slack_s)
    if weight is not None:
        closes = robust_closes(qs, epoch, opens, closes, weight, end_s, cadence_s, timing, sky)
    return opens, closes


def _run(qs, epoch, opens, closes, start_s, end_s, timing, sky):
    trial = replace(qs, window_start_s=opens.copy(), window_end_s=np.where(np.isfinite(opens), closes, -math.inf))
    return execute_queues(trial, epoch, start_s, end_s, timing, sky=sky)


def _cadence_open(qs, epoch, opens, closes, rows, planned_s, s_k, end_s, separation_s, timing, sky, k) -> float:
    """(Q11) the earliest opening of pass ``k`` that keeps each of its fields ``separation_s`` after its other filter."""
    if k == 0 or not np.isfinite(opens[:k]).any():
        return -math.inf
    done = _run(qs, epoch, opens, closes, float(np.min(planned_s)), min(end_s, s_k + 3600.0), timing, sky)
    need = -math.inf
    for d in done:
        if d.status != "processed":
            continue
        same = rows[(qs.field_id[rows] == qs.field_id[d.target]) & (qs.filter_id[rows] != qs.filter_id[d.target])]
        for j in same:
            need = max(need, d.start_s + separation_s - (float(planned_s[j]) - s_k))
    return need
