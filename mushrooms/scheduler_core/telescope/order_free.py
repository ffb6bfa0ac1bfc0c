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

(Q20) the closes are made so that no switch of the modelled on-time run has
a choice.  At the first switch with two or more queues open and not empty
(the run under ztf_sim's rules, :func:`~.executor.first_switch_conflict`),
one of them is kept and the others are closed one second before it (a
queue closed before it opens is not exported); the one kept is the one
whose run keeps the most pair weight (Q17's order,
:func:`~.late_windows.rule_values`: ztf_sim's rule, then first-wins; ties:
the last in submission order, ztf_sim's own choice).  Repeated until no switch has a choice: then first-wins and
last-wins make the same choice at every switch of that run.
"""

from __future__ import annotations

import math
from dataclasses import replace
import numpy as np
from astropy.time import Time

from .executor import QueueSet, SkyGrid, first_switch_conflict
from .late_windows import better, rule_values
from .timing import TelescopeTiming

__all__ = ["order_free_windows", "MAX_FIXES"]

#: Most switches resolved per queue set (a bound: each fix closes a queue earlier).
MAX_FIXES = 64
#: A queue closed at a switch closes this long (s) before it.
BEFORE_S = 1.0


def order_free_windows(qs: QueueSet, epoch: Time, opens: np.ndarray, closes: np.ndarray, start_s: float,
                       end_s: float, weight: np.ndarray, cadence_s: float,
                       timing: TelescopeTiming = TelescopeTiming(), sky: SkyGrid | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """(Q20) opens and closes under which no switch of the run from ``start_s`` has more than one queue to take.

    Parameters
    ----------
    qs : QueueSet
        One queue per pass, in submission order.
    epoch : astropy.time.Time
        Time zero.
    opens, closes : numpy.ndarray
        (K,) the windows (s since ``epoch``; ``open = inf``: not exported).
    start_s, end_s : float
        The run: the telescope free at ``start_s``, the plan's end (s since ``epoch``).
    weight : numpy.ndarray
        (n,) each target's field weight (Q17's ``V``).
    cadence_s : float
        The cadence (s).
    timing : TelescopeTiming
        The telescope model (its ``rules.switch`` is ignored: both are played).
    sky : SkyGrid, optional
        Observability of ``qs``'s targets.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The opens (a queue closed before it opens gets ``inf``) and closes.
    """
    opens, closes = opens.astype(float).copy(), closes.astype(float).copy()
    for _ in range(MAX_FIXES):
        hit = first_switch_conflict(_windows(qs, opens, closes), epoch, start_s, end_s, timing, sky)
        if hit is None:
            break
        t, ks = hit
        best = None
        for keep in reversed(ks):  # the last first: ztf_sim's own choice wins a tie
            o, c = _keep_one(opens, closes, ks, keep, t)
            value = rule_values(qs, epoch, o, c, [(start_s, timing)], end_s, weight, cadence_s, sky)
            if best is None or better(value, best[0]):
                best = (value, o, c)
        opens, closes = best[1], best[2]
    return opens, closes


def _keep_one(opens: np.ndarray, closes: np.ndarray, ks: tuple[int, ...], keep: int, t: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """Every queue of ``ks`` but ``keep`` closed just before ``t`` (not exported when that is before it opens).

    Just before ``t``, not before the kept queue opened: a late telescope still finds the closed queue open
    where the on-time run had finished with it (closing it sooner kept less, late, on the shared maps).
    """
    o, c = opens.copy(), closes.copy()
    for k in ks:
        if k != keep:
            c[k] = min(c[k], t - BEFORE_S)
            if not c[k] > o[k]:
                o[k] = math.inf
    return o, c


def _windows(qs: QueueSet, opens: np.ndarray, closes: np.ndarray) -> QueueSet:
    return replace(qs, window_start_s=opens.copy(), window_end_s=np.where(np.isfinite(opens), closes, -math.inf))
