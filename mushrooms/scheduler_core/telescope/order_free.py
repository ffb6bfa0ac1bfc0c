"""Queue sets that ZTF's scheduler executes the same whichever open queue it takes (Q20, ``docs/design/executed.md``).

ztf_sim's main loop hands the telescope from its default queue to the
*last* valid, non-empty queue in submission order (Q1,
``check_for_timed_queue_and_switch``); the ToO switch beside it, and the
executor before issue 52, take the *first*.  Both take the same queue
whenever one queue alone is open and not empty at a switch, and then the
whole run is the same.  The pass queues of a plan overlap (Q12: a pass
stays open a slack after its modelled end, so a late telescope finishes it),
so two of them can be open at a switch: an earlier pass holding targets it
could not observe on its turn, beside the next pass.  First-wins goes back
to the earlier one at every switch (a survey exposure each time, Q3, until
its window closes); last-wins takes the next.

(Q20) the closes are made so that no switch of the modelled run has a
choice.  At the first switch with two or more queues open and not empty
(the run under ztf_sim's rules, :func:`~.executor.first_switch_conflict`),
one of them is kept and the others are closed one second before it (a
queue closed before it opens is not exported); the one kept is the one
whose run keeps the most pair weight (:func:`~.late_windows.pair_value`;
ties: the last in submission order, ztf_sim's own choice).  Repeated until
no switch has a choice.  First on time (the run ``coverage_as_executed``
reports); then, when the closes are chosen for a late or off-speed telescope
(Q16-Q18), in each of those runs too, a choice there being resolved only by
closes that leave the on-time run exactly as it was.  Closing a queue
earlier never adds a choice to a run it leaves unchanged.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np
from astropy.time import Time

from .executor import ExecutedTarget, QueueSet, SkyGrid, execute_queues, first_switch_conflict
from .late_windows import pair_value
from .timing import TelescopeTiming

__all__ = ["order_free_windows", "Scenario", "MAX_FIXES"]

#: A run of the queues: the telescope free at this time (s since the epoch), with this timing.
Scenario = tuple[float, TelescopeTiming]
#: Most switches resolved per queue set (a bound: each fix closes a queue earlier).
MAX_FIXES = 64
#: A queue closed at a switch closes this long (s) before it.
BEFORE_S = 1.0


def order_free_windows(qs: QueueSet, epoch: Time, opens: np.ndarray, closes: np.ndarray, end_s: float,
                       weight: np.ndarray, cadence_s: float, scenarios: Sequence[Scenario], sky: SkyGrid,
                       keep_on_time: Scenario | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(Q20) opens and closes under which no switch of the given runs has more than one queue to take.

    Parameters
    ----------
    qs : QueueSet
        One queue per pass, in submission order.
    epoch : astropy.time.Time
        Time zero.
    opens, closes : numpy.ndarray
        (K,) the windows (s since ``epoch``; ``open = inf``: not exported).
    end_s, cadence_s : float
        The plan's end and the cadence (s).
    weight : numpy.ndarray
        (n,) each target's field weight (Q17's ``V``).
    scenarios : sequence of (float, TelescopeTiming)
        The runs made free of choices, in this order.
    sky : SkyGrid
        Observability of ``qs``'s targets.
    keep_on_time : (float, TelescopeTiming), optional
        A run that must stay exactly as it is (a choice no fix can resolve
        without changing it is left).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The opens (a queue closed before it opens gets ``inf``) and closes.
    """
    opens, closes = opens.astype(float).copy(), closes.astype(float).copy()
    base = None if keep_on_time is None else _run(qs, epoch, opens, closes, keep_on_time, end_s, sky)
    left = list(scenarios)
    for _ in range(MAX_FIXES):
        hit = _first_choice(qs, epoch, opens, closes, left, end_s, sky)
        if hit is None:
            break
        scenario, (t, ks) = hit
        fixed = _best_fix(qs, epoch, opens, closes, t, ks, left, end_s, weight, cadence_s, sky, base, keep_on_time)
        if fixed is None:
            left.remove(scenario)  # no fix keeps the protected run: this run keeps its choice
            continue
        opens, closes = fixed
    return opens, closes


def _first_choice(qs, epoch, opens, closes, scenarios, end_s, sky):
    """The first scenario with a switch that has a choice, and that switch."""
    trial = _windows(qs, opens, closes)
    for scenario in scenarios:
        start, timing = scenario
        hit = first_switch_conflict(trial, epoch, start, end_s, timing, sky)
        if hit is not None:
            return scenario, hit
    return None


def _best_fix(qs, epoch, opens, closes, t, ks, scenarios, end_s, weight, cadence_s, sky, base, keep_on_time):
    """Keep one of the queues ``ks`` open at ``t``, close the others just before: the fix keeping most weight."""
    best = None
    for keep in reversed(ks):  # the last first: ztf_sim's own choice wins a tie
        o, c = opens.copy(), closes.copy()
        for k in ks:
            if k != keep:
                c[k] = min(c[k], t - BEFORE_S)
                if not c[k] > o[k]:
                    o[k] = math.inf  # closed before it opened: not exported
        if base is not None and _run(qs, epoch, o, c, keep_on_time, end_s, sky) != base:
            continue
        value = sum(pair_value(qs, _run(qs, epoch, o, c, s, end_s, sky), weight, cadence_s) for s in scenarios)
        if best is None or value > best[0] + 1e-12:
            best = (value, o, c)
    return None if best is None else best[1:]


def _windows(qs: QueueSet, opens: np.ndarray, closes: np.ndarray) -> QueueSet:
    return replace(qs, window_start_s=opens.copy(), window_end_s=np.where(np.isfinite(opens), closes, -math.inf))


def _run(qs, epoch, opens, closes, scenario: Scenario, end_s, sky) -> tuple[ExecutedTarget, ...]:
    start, timing = scenario
    return execute_queues(_windows(qs, opens, closes), epoch, start, end_s, timing, sky=sky)
