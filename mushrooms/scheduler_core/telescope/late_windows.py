"""Window closes that make a late or slower telescope lose time, not pairs (Q16-Q18, ``docs/design/executed.md``).

The opens of a plan's pass queues (Q11) hold the cadence when the telescope
starts on time.  When it starts late (another ToO, the weather), the
scheduler still plays every open queue as soon as it can, in submission
order (Q1): a late first-filter pass runs on inside its window while its
second-filter pass, open already, follows it back to back, below the
cadence; a second-filter pass whose first filter was never taken runs for
nothing and pushes the passes after it.  Both are decided by the closes.

* (Q16) each pass k has two candidate closes: the wide one of Q12
  (``slack`` after the model's end of the pass: a late pass is shifted,
  its partner after it) and the tight one
  ``last_k + max(0, e_k)``, ``last_k`` the model's start of the pass's
  last exposure on time (with ``emptied = "survey"``, Q3, at least 1 s
  after that exposure's end: the choice after it must see the queue open), ``e_k = min_j (t2_j - t1_j) - cadence`` the least
  excess separation of the pass's pairs on time (0 for a pass without
  pairs): a pass late by more than its pairs' excess is cut.
* (Q17) the value of a set of closes in a scenario ``s`` is the weight of the
  fields the executor (Q1-Q10) takes in both filters at least the cadence
  apart, ``V_s = Σ_f w_f [pair of f valid]``, ``w_f`` the field's
  probability share in the plan, summed over the scenarios as ztf_sim's
  main loop runs them (the last open queue taken, Q1), ties broken by the
  same sum with the first open queue taken: the closes are chosen for
  ztf_sim, and for a first-wins scheduler where that costs ztf_sim nothing.
  Scenarios: the telescope free 15, 30 and 60 min late, and on time with
  every overhead x0.8 and x1.2.
* (Q18) the closes are chosen pass by pass in plan order, starting from the
  wide ones: pass k takes its tight close when that raises ``Σ_s V_s``
  (Q17's order; ties keep the wide one) and leaves the on-time run at the modelled speed
  exactly as it was (checked: a run that takes every target of the pass,
  each exposure ending by the tight close, is left as it was; any other
  is run again): the executed plan and ``coverage_as_executed`` are the same with
  either close.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np
from astropy.time import Time

from .executor import ExecutedTarget, QueueSet, SkyGrid, execute_queues
from .timing import TelescopeTiming

__all__ = ["robust_closes", "pair_value", "rule_values", "better", "LATE_SCENARIOS_S", "SPEED_SCENARIOS", "RULE_ORDER"]

#: Late starts (s) the closes are chosen for (Q17).
LATE_SCENARIOS_S = (900.0, 1800.0, 3600.0)
#: Overhead factors (slower > 1, faster < 1) of an on-time telescope the closes are chosen for (Q17).
SPEED_SCENARIOS = (0.8, 1.2)
#: With ``emptied = "survey"`` a tight close is at least this long (s) after the pass's last exposure ends
#: (the window's MJD is rounded).
AFTER_END_S = 1.0
#: The switch rules a set of windows is valued under, in order of weight (Q17): ztf_sim's, then first-wins.
RULE_ORDER = ("last", "first")


def pair_value(qs: QueueSet, done: Sequence[ExecutedTarget], weight: np.ndarray, cadence_s: float) -> float:
    """(Q17) the weight of the fields taken in two filters at least ``cadence_s`` apart.

    Parameters
    ----------
    qs : QueueSet
        The queues run.
    done : sequence of ExecutedTarget
        The executor's exposures (only ``processed`` ones count).
    weight : numpy.ndarray
        (n,) each target's field weight (e.g. its probability share).
    cadence_s : float
        Least separation (s) of a field's two filters.
    """
    seen: dict[int, list[tuple[int, float]]] = {}
    for d in done:
        if d.status == "processed":
            seen.setdefault(int(qs.field_id[d.target]), []).append((int(qs.filter_id[d.target]), d.start_s))
    value = 0.0
    for field, visits in seen.items():
        if any(b1 != b2 and abs(t2 - t1) >= cadence_s for b1, t1 in visits for b2, t2 in visits):
            value += float(weight[qs.field_id == field].max())
    return value


def rule_values(qs: QueueSet, epoch: Time, opens: np.ndarray, closes: np.ndarray,
                runs: Sequence[tuple[float, TelescopeTiming]], end_s: float, weight: np.ndarray,
                cadence_s: float, sky: SkyGrid | None = None) -> tuple[float, float]:
    """(Q17) the pair weight kept over ``runs`` (start, timing): last-wins (ztf_sim's main loop), then first-wins (Q1).

    Compared as a pair, in that order: a set of windows is better when ztf_sim keeps more, or as much and a
    first-wins scheduler more.

    Parameters
    ----------
    qs : QueueSet
        The queues (their windows are ``opens``, ``closes``; ``open = inf``: not exported).
    epoch : astropy.time.Time
        Time zero.
    opens, closes : numpy.ndarray
        (K,) windows (s since ``epoch``).
    runs : sequence of (float, TelescopeTiming)
        When the telescope is free and how fast it is.
    end_s, cadence_s : float
        The plan's end and the cadence (s).
    weight : numpy.ndarray
        (n,) each target's field weight.
    sky : SkyGrid, optional
        Observability of ``qs``'s targets.
    """
    return tuple(sum(pair_value(qs, _play(qs, epoch, opens, closes, start, end_s, timing.with_switch(rule), sky),
                                weight, cadence_s) for start, timing in runs) for rule in RULE_ORDER)  # type: ignore


def better(a: tuple[float, float], b: tuple[float, float] | None, tol: float = 1e-12) -> bool:
    """(Q17) ``a`` keeps more than ``b``: more last-wins, or as much and more first-wins (None: anything is)."""
    return b is None or a[0] > b[0] + tol or (a[0] > b[0] - tol and a[1] > b[1] + tol)


def robust_closes(qs: QueueSet, epoch: Time, opens: np.ndarray, closes: np.ndarray, weight: np.ndarray,
                  end_s: float, cadence_s: float, timing: TelescopeTiming = TelescopeTiming(),
                  sky: SkyGrid | None = None, lates_s: Sequence[float] = LATE_SCENARIOS_S,
                  speeds: Sequence[float] = SPEED_SCENARIOS) -> np.ndarray:
    """(Q16-Q18) the closes of the pass queues, each wide or tight, whichever keeps more pairs late or off-speed.

    Parameters
    ----------
    qs : QueueSet
        One queue per pass, in submission order.
    epoch : astropy.time.Time
        Time zero.
    opens, closes : numpy.ndarray
        (K,) the opens (Q11; ``inf`` for a pass not exported) and wide closes (Q12), s since ``epoch``.
    weight : numpy.ndarray
        (n,) each target's field weight.
    end_s, cadence_s : float
        The plan's end and the cadence (s).
    timing : TelescopeTiming
        The telescope as modelled.
    sky : SkyGrid, optional
        Observability of ``qs``'s targets (built when missing).
    lates_s, speeds : sequence of float
        The scenarios (Q17).

    Returns
    -------
    numpy.ndarray
        (K,) the chosen closes.
    """
    exported = np.isfinite(opens)
    if not exported.any():
        return closes.copy()
    first = float(opens[exported].min())
    if sky is None:
        sky = SkyGrid(qs, epoch, first, end_s, 60.0, timing)
    base = _play(qs, epoch, opens, closes, first, end_s, timing, sky)
    on_time = {d.target: d.start_s for d in base if d.status == "processed"}
    scenarios = [(start, t.with_switch(rule))  # each scenario as ztf_sim's main loop runs it, then first-wins
                 for start, t in [(first + late, timing) for late in lates_s] + [(first, timing.scaled(f))
                                                                                 for f in speeds]
                 for rule in RULE_ORDER]

    def runs(trial: np.ndarray) -> list[tuple[ExecutedTarget, ...]]:
        return [_play(qs, epoch, opens, trial, start, end_s, t, sky) for start, t in scenarios]

    def score(played: list[tuple[ExecutedTarget, ...]]) -> tuple[float, float]:
        """(Σ_s V_s last-wins, Σ_s V_s first-wins), compared in that order."""
        values = [pair_value(qs, run, weight, cadence_s) for run in played]
        return sum(values[0::2]), sum(values[1::2])

    chosen = closes.copy()
    played = runs(chosen)
    best = score(played)
    for k in np.flatnonzero(exported):
        tight = _tight_close(qs, k, on_time, cadence_s, timing.rules.emptied == "survey")
        if tight is None or not tight < chosen[k]:
            continue
        if all(_untouched(qs, k, run, tight, chosen[k], start) for run, (start, _) in zip(played, scenarios)):
            continue  # the tight close would change none of the runs: a tie, the wide one stays
        trial = chosen.copy()
        trial[k] = tight
        if not _untouched(qs, k, base, tight, chosen[k], first) and \
                _play(qs, epoch, opens, trial, first, end_s, timing, sky) != base:
            continue  # (Q18) the on-time run must stay the same (a target left over for later, say)
        trial_played = runs(trial)
        value = score(trial_played)
        if better(value, best):
            best, chosen, played = value, trial, trial_played
    return chosen


def _untouched(qs: QueueSet, k: int, run: Sequence[ExecutedTarget], tight: float, wide: float,
               start_s: float) -> bool:
    """True when closing pass ``k`` at ``tight`` instead of ``wide`` cannot change ``run`` (started at ``start_s``).

    Either the wide window had closed before the run began, or every target of the pass was taken with its
    exposure ending by ``tight``: each choice of the pass came no later, the pass was then empty, and the
    choice after its last exposure -- where ``simulate.py``'s scheduler finds the queue emptied inside its
    window and lets the survey take one exposure (Q3, ``emptied = "survey"``) -- still saw it open.
    """
    if wide < start_s:
        return True
    ended = {d.target: d.start_s + d.exposure_s for d in run if d.status == "processed"}
    return all(int(j) in ended and ended[int(j)] <= tight for j in np.flatnonzero(qs.queue == k))


def _tight_close(qs: QueueSet, k: int, on_time: dict[int, float], cadence_s: float,
                 survey_when_emptied: bool = False) -> float | None:
    """(Q16) ``last_k + max(0, e_k)``: the start of the pass's last exposure on time plus its pairs' least
    excess; with ``emptied = "survey"`` never before that exposure ends.

    There the choice after the last exposure must still find the queue open, as the wide window does, or the
    on-time run loses the survey exposure ``simulate.py`` takes there (Q3) and changes.
    """
    rows = [int(j) for j in np.flatnonzero(qs.queue == k) if j in on_time]
    if not rows:
        return None
    excess = math.inf
    for j in rows:
        other = np.flatnonzero((qs.field_id == qs.field_id[j]) & (qs.filter_id != qs.filter_id[j]))
        for p in other:
            if int(p) in on_time:
                excess = min(excess, abs(on_time[int(p)] - on_time[j]) - cadence_s)
    last = max(rows, key=lambda j: on_time[j])
    tight = on_time[last] + (max(0.0, excess) if math.isfinite(excess) else 0.0)
    if not survey_when_emptied:
        return tight
    return max(tight, on_time[last] + float(qs.exposure_s[last]) + AFTER_END_S)


def _play(qs, epoch, opens, closes, start_s, end_s, timing, sky):
    trial = replace(qs, window_start_s=opens.copy(), window_end_s=np.where(np.isfinite(opens), closes, -math.inf))
    return execute_queues(trial, epoch, start_s, end_s, timing, sky=sky)
