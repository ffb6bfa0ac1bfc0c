"""Completing half-done pairs: the single exposures a re-plan pins (P3-P7).

A field the telescope observed in one filter only (:func:`~..executed.done_pairs`'s
``one``) needs one more exposure, in its other filter, at least the cadence
after the first, to count as covered.  That exposure costs half of a new
pair, so it is placed before the schedulers see the rest of the night:

* :func:`completion_pass` (P4) walks from the re-plan's start and takes, one
  at a time, the visit that is due, observable and adds the most
  not-yet-covered probability (at least ``min_gain``, P3), keeping one filter
  as long as it can;
* :func:`drop_repeats` (P6) removes, from a field the scheduler planned as
  a whole new pair, the exposure in the filter already done, when the other
  one is due;
* :func:`insert_completions` (P7) puts the visits that were not due yet into
  the gaps of the finished plan (the earliest gap where the overheads on
  both sides, the due time and a window allow), and failing that
  (:func:`swap_in_completions`) in the place of a planned field that adds
  less than the completion would;
* :func:`shift_in_completions` (F3) makes room for a sequence's next visit
  by delaying what follows it, and :func:`trim_to_rules` (F9) then drops
  what the delay made break its field's rules (span, window, latest start),
  keeping the credit F1 allows.

Times are seconds since the re-plan's start.  The equations are in
``docs/design/replan.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from ..config import PlanningConfig
from ..plan.document import Observation
from ..sky.footprints import Footprints
from ..sky.windows import Windows
from ..telescope.slew import overhead_time

__all__ = ["PendingVisit", "completion_pass", "insert_completions", "swap_in_completions", "shift_in_completions",
           "trim_to_rules", "drop_repeats", "gains_of"]


@dataclass(frozen=True)
class PendingVisit:
    """The exposure a half-done field still needs (P2).

    Attributes
    ----------
    field_id : int
        ZTF field ID.
    ra, dec : float
        Field centre (deg).
    filter : str
        The filter still to observe (the pair's other filter).
    due_s : float
        Earliest start (s since the re-plan's start) keeping the cadence
        after the field's first done exposure; never below 0.
    latest_s : float
        (P10) Latest start (s since the re-plan's start) still pairing with
        the first done exposure: ``pair_max_s`` after it (default no limit).
    worth : float or None
        (F3) What the visit is worth when it adds no coverage (a covered
        field's later visit of a sequence, e.g. the g after g, r of
        g-r-g): used instead of the probability it would add.  None (a
        pair's completion): the probability it adds.
    """

    field_id: int
    ra: float
    dec: float
    filter: str
    due_s: float
    latest_s: float = float("inf")
    worth: float | None = None


def gains_of(visits: Sequence[PendingVisit], footprints: Footprints, uncovered: np.ndarray) -> np.ndarray:
    """(n,) probability still uncovered inside each visit's field (its gain if completed now; F3: its ``worth``)."""
    if not visits:
        return np.zeros(0)
    sub = footprints.subset([v.field_id for v in visits])
    gain = sub.field_probability(uncovered)
    fixed = np.array([v.worth is not None for v in visits])
    if fixed.any():
        gain = np.where(fixed, [v.worth or 0.0 for v in visits], gain)
    return gain


def _worth(gain: np.ndarray, min_gain: float) -> np.ndarray:
    """(P3) a completion is worth an exposure when it adds some probability, at least ``min_gain``."""
    return (gain > 0) & (gain >= min_gain)


def _earliest_for(v: PendingVisit, t: float, exposure_s: float, windows: Windows) -> float | None:
    """The visit's earliest start at or after ``t`` inside a window, and (P10) no later than ``v.latest_s``."""
    s = _earliest_in_window(v.field_id, t, exposure_s, windows)
    return None if s is None or s > v.latest_s else s


def _earliest_in_window(field_id: int, t: float, exposure_s: float, windows: Windows) -> float | None:
    """Earliest start >= ``t`` with ``[s, s + exposure]`` inside a window of the field (None: none)."""
    for w0, w1 in windows.for_field(field_id):
        s = max(t, w0)
        if s + exposure_s <= w1:
            return s
    return None


def completion_pass(visits: Sequence[PendingVisit], footprints: Footprints, uncovered: np.ndarray,
                    windows: Windows, config: PlanningConfig, block: int = 0
                    ) -> tuple[tuple[Observation, ...], tuple[PendingVisit, ...], np.ndarray]:
    """The front pass of completions (P4): what is due, from the start, waiting at most one exposure's time.

    Parameters
    ----------
    visits : sequence of PendingVisit
        The half-done fields' missing exposures.
    footprints : Footprints
        Holding at least the visits' fields.
    uncovered : numpy.ndarray
        Probability per pixel not covered yet (P1); not modified.
    windows : Windows
        Observability windows (s since the start) of at least the visits' fields.
    config : PlanningConfig
        Exposure, filters, overheads, horizon, least gain.
    block : int
        Block number of the pass's exposures.

    Returns
    -------
    observations : tuple of Observation
        The pass, in time order; the first starts at 0.
    left : tuple of PendingVisit
        Visits still worth completing that the pass did not take (not due,
        or not observable, when it reached them).
    uncovered : numpy.ndarray
        ``uncovered`` with the pass's fields' pixels set to 0.
    """
    uncovered = uncovered.copy()
    exp, horizon = config.exposure_s, config.horizon_s
    wait = exp + config.slew_estimate_s  # (P4) the longest wait: one exposure's time
    left = list(visits)
    out: list[Observation] = []
    t, prev = 0.0, None
    while left:
        gain = gains_of(left, footprints, uncovered)
        ra = np.array([v.ra for v in left])
        dec = np.array([v.dec for v in left])
        filt = np.array([v.filter for v in left])
        if prev is None:
            ready = np.full(len(left), t)
        else:
            change = np.where(filt != prev[2], config.filter_change_s, 0.0)
            ready = t + overhead_time(prev[0], prev[1], ra, dec, config.slew, change)
        s = np.full(len(left), np.inf)
        for i, v in enumerate(left):
            at = _earliest_for(v, max(float(ready[i]), v.due_s), exp, windows)
            s[i] = np.inf if at is None else at
        ok = _worth(gain, config.min_gain) & (s <= ready + wait) & (s + exp <= horizon)
        if not ok.any():
            break
        # keep the filter in the wheel while it has work; at the start, the filter holding more gain
        if prev is None:
            per = {f: gain[ok & (filt == f)].sum() for f in set(filt[ok].tolist())}
            current = max(sorted(per), key=lambda f: per[f])
        else:
            current = prev[2]
        pool = ok & (filt == current)
        pool = pool if pool.any() else ok
        k = int(np.argmax(np.where(pool, gain, -1.0)))
        v = left.pop(k)
        out.append(Observation(v.field_id, v.ra, v.dec, v.filter, float(s[k]), exp, block))
        uncovered[footprints.pixels(v.field_id)] = 0.0
        t, prev = float(s[k]) + exp, (v.ra, v.dec, v.filter)
    gain = gains_of(left, footprints, uncovered)
    still = tuple(v for v, worth in zip(left, _worth(gain, config.min_gain)) if worth)
    return tuple(out), still, uncovered


def insert_completions(observations: Sequence[Observation], visits: Sequence[PendingVisit],
                       footprints: Footprints, uncovered: np.ndarray, windows: Windows,
                       config: PlanningConfig) -> tuple[tuple[Observation, ...], tuple[PendingVisit, ...]]:
    """Fit pending visits into the gaps of a plan (P7), most gain first.

    A visit goes into the earliest gap between two consecutive exposures
    ``a, b`` (or after the last one) where, with ``o`` the overhead,
    ``s = max(end_a + o(a, v), due_v, window opening)`` satisfies
    ``s + t_exp + o(v, b) <= start_b``, ``[s, s + t_exp]`` inside a window
    of the field and ``s + t_exp <= H``.  Fields the plan already observes
    are skipped (the plan covers them).

    Parameters
    ----------
    observations : sequence of Observation
        The plan, times in s since the start.
    visits : sequence of PendingVisit
        Visits to place.
    footprints : Footprints
        Holding at least the visits' fields.
    uncovered : numpy.ndarray
        Probability per pixel not covered by the executed pairs nor the
        plan; not modified.
    windows : Windows
        Observability windows (s since the start).
    config : PlanningConfig

    Returns
    -------
    observations : tuple of Observation
        The plan with the visits placed, in time order.
    left : tuple of PendingVisit
        Visits no gap could take, or no longer worth it beside the plan.
    """
    plan = sorted(observations, key=lambda o: o.start)
    uncovered = uncovered.copy()
    planned = {o.field_id for o in plan}
    todo = [v for v in visits if v.field_id not in planned]
    gain = gains_of(todo, footprints, uncovered)
    left: list[PendingVisit] = []
    exp = config.exposure_s
    for k in np.argsort(-gain, kind="stable"):
        v = todo[int(k)]
        g = float(gains_of([v], footprints, uncovered)[0])
        placed = _place(plan, v, windows, config) if _worth(np.array([g]), config.min_gain)[0] else None
        if placed is None:
            left.append(v)
            continue
        i, s = placed
        block = plan[i - 1].block if i > 0 else 0
        plan.insert(i, Observation(v.field_id, v.ra, v.dec, v.filter, s, exp, block))
        uncovered[footprints.pixels(v.field_id)] = 0.0
    return tuple(plan), tuple(left)


def swap_in_completions(observations: Sequence[Observation], visits: Sequence[PendingVisit],
                        footprints: Footprints, prob: np.ndarray, windows: Windows, config: PlanningConfig,
                        keep: set[int] = frozenset()) -> tuple[tuple[Observation, ...], tuple[PendingVisit, ...]]:
    """Give a pending visit the place of a planned field that adds less (P7, the swap).

    For each visit (largest gain first), the planned fields not in ``keep``
    are tried in increasing order of the probability only they cover (on
    ``prob``): the field's exposures are removed and the visit placed as in
    :func:`insert_completions`; the swap is kept when the visit then adds
    more than the removed field did (and at least ``min_gain``).

    Parameters
    ----------
    observations : sequence of Observation
        The plan (s since the start).
    visits : sequence of PendingVisit
        Visits no gap took.
    footprints : Footprints
        Holding the plan's and the visits' fields.
    prob : numpy.ndarray
        Probability per pixel not covered by the executed pairs (P1).
    windows : Windows
    config : PlanningConfig
    keep : set of int
        Fields never removed (the completions already placed).

    Returns
    -------
    observations : tuple of Observation
        In time order.
    left : tuple of PendingVisit
        Visits that found no place.
    """
    plan = sorted(observations, key=lambda o: o.start)
    left: list[PendingVisit] = []
    keep = set(keep)
    for v in visits:
        counts = np.zeros(prob.shape, dtype=np.int32)
        fields = list(dict.fromkeys(o.field_id for o in plan))
        for fid in fields:
            counts[footprints.pixels(fid)] += 1
        own = {fid: float(prob[footprints.pixels(fid)][counts[footprints.pixels(fid)] == 1].sum()) for fid in fields}
        pix_v = footprints.pixels(v.field_id)
        done = False
        for fid in sorted((f for f in fields if f not in keep), key=lambda f: own[f]):
            gain_v = float(prob[pix_v][counts[pix_v] - np.isin(pix_v, footprints.pixels(fid)) == 0].sum())
            if gain_v <= own[fid] or not _worth(np.array([gain_v]), config.min_gain)[0]:
                continue
            trial = [o for o in plan if o.field_id != fid]
            placed = _place(trial, v, windows, config)
            if placed is None:
                continue
            i, s = placed
            block = trial[i - 1].block if i > 0 else 0
            trial.insert(i, Observation(v.field_id, v.ra, v.dec, v.filter, s, config.exposure_s, block))
            plan, done = trial, True
            keep.add(v.field_id)
            break
        if not done:
            left.append(v)
    return tuple(plan), tuple(left)


def shift_in_completions(observations: Sequence[Observation], visits: Sequence[PendingVisit], windows: Windows,
                         config: PlanningConfig, pending: Sequence[PendingVisit] = ()
                         ) -> tuple[tuple[Observation, ...], tuple[PendingVisit, ...]]:
    """(F3) Make room for a sequence's next visits: insert each, most worth first, delaying what follows it.

    A visit goes at the earliest place where it can start at or after its
    due time inside a window; every later exposure moves by the same delay.
    A field with visits on both sides of the insertion is stretched by it,
    and a moved exposure may leave its window, the horizon or (a pending
    visit) its ``latest_s``: (F9) what then breaks its rules goes, by
    :func:`trim_to_rules`.  Only visits with a ``worth`` (a covered field's
    next visit) are placed; the others come back in ``left``.

    Parameters
    ----------
    observations : sequence of Observation
        The plan (s since the start).
    visits : sequence of PendingVisit
        The visits no gap took.
    windows : Windows
        Observability windows (s since the start) of the plan's and the visits' fields.
    config : PlanningConfig
        Exposure, overheads, horizon, sequence, cadence and pair separation.
    pending : sequence of PendingVisit
        Every pending visit of the re-plan (those already in the plan
        included): a field with one is a continuation (F7), held to its
        visit's ``latest_s``.

    Returns
    -------
    observations : tuple of Observation
        The plan with the visits, in time order.
    left : tuple of PendingVisit
        Visits that found no place.
    """
    plan = sorted(observations, key=lambda o: o.start)
    latest = {v.field_id: v.latest_s for v in (*pending, *visits) if v.worth is not None}
    left: list[PendingVisit] = []
    for v in sorted(visits, key=lambda v: -(v.worth or 0.0)):
        moved = None if v.worth is None else _shift_in(plan, v, windows, config)
        if moved is None:
            left.append(v)
        else:
            plan = trim_to_rules(moved, latest, windows, config)
    return tuple(plan), tuple(left)


def _shift_in(plan: list[Observation], v: PendingVisit, windows: Windows,
              config: PlanningConfig) -> list[Observation] | None:
    """The plan with ``v`` at its earliest place, the exposures after it delayed; None when none holds it."""
    exp = config.exposure_s
    for i in range(len(plan) + 1):
        prev = plan[i - 1] if i else None
        ready = 0.0 if prev is None else prev.end + float(overhead_time(
            prev.ra, prev.dec, v.ra, v.dec, config.slew, config.filter_change_s if prev.filter != v.filter else 0.0))
        s = _earliest_for(v, max(ready, v.due_s), exp, windows)
        if s is None or s + exp > config.horizon_s:
            continue
        if i < len(plan) and s > plan[i].start:
            continue  # it would start after the next exposure: a later place
        nxt = plan[i] if i < len(plan) else None
        delay = 0.0 if nxt is None else max(0.0, s + exp + float(overhead_time(
            v.ra, v.dec, nxt.ra, nxt.dec, config.slew,
            config.filter_change_s if nxt.filter != v.filter else 0.0)) - nxt.start)
        after = [o if delay == 0.0 else replace(o, start=o.start + delay) for o in plan[i:]]
        block = prev.block if prev is not None else 0
        return plan[:i] + [Observation(v.field_id, v.ra, v.dec, v.filter, s, exp, block)] + after
    return None


def trim_to_rules(plan: Sequence[Observation], latest: Mapping[int, float], windows: Windows,
                  config: PlanningConfig) -> list[Observation]:
    """(F9) Drop what a shift left breaking its field's rules, keeping all the credit F1 allows.

    An exposure is *in place* when it lies inside a window of its field and
    ends within the horizon.  A continuation (a field in ``latest``: its
    covering pair is executed, F7) keeps the visits in place that start by
    its ``latest_s`` (they add no coverage: dropping one loses no credit).
    A field planned anew (F6) keeps its longest prefix of visits in place,
    each at least the cadence after the one before, the last at most the
    pair separation after the first; when that prefix holds the sequence's
    first two visits (its covering pair: F1 credits it whole) it stays,
    else the field goes, all of it (a lone first visit is credited
    nothing).  Removing exposures never breaks the overheads of the rest.

    Parameters
    ----------
    plan : sequence of Observation
        In time order (s since the start).
    latest : mapping of int to float
        Continuing field -> latest start of its next visit (s).
    windows : Windows
    config : PlanningConfig

    Returns
    -------
    list of Observation
        ``plan`` without the exposures that break their field's rules, in time order.
    """
    tol = 1e-3
    credited = min(2, len(config.filters))
    keep: set[int] = set()
    by_field: dict[int, list[int]] = {}
    for i, o in enumerate(plan):
        by_field.setdefault(o.field_id, []).append(i)
    for fid, rows in by_field.items():
        in_place = [i for i in rows if plan[i].end <= config.horizon_s + tol
                    and windows.contains(fid, plan[i].start + tol, plan[i].end - tol)]
        if fid in latest:
            keep.update(i for i in in_place if plan[i].start <= latest[fid] + tol)
            continue
        prefix = [rows[0]] if rows[0] in in_place else []
        for i in rows[1:] if prefix else ():
            first, last = plan[prefix[0]], plan[prefix[-1]]
            if (i not in in_place or plan[i].start - last.start < config.cadence_s - tol
                    or plan[i].start - first.start > config.pair_separation_s + tol):
                break
            prefix.append(i)
        if len(prefix) >= credited:
            keep.update(prefix)
    return [o for i, o in enumerate(plan) if i in keep]


def _place(plan: list[Observation], v: PendingVisit, windows: Windows,
           config: PlanningConfig) -> tuple[int, float] | None:
    """(index to insert at, start) of the earliest gap that takes the visit, or None."""
    exp = config.exposure_s
    n = len(plan)
    if n == 0:
        s = _earliest_for(v, v.due_s, exp, windows)
        return None if s is None or s + exp > config.horizon_s else (0, s)
    ra = np.array([o.ra for o in plan])
    dec = np.array([o.dec for o in plan])
    filt = np.array([o.filter for o in plan])
    start = np.array([o.start for o in plan])
    end = start + np.array([o.exposure_s for o in plan])
    change = np.where(filt != v.filter, config.filter_change_s, 0.0)
    into = overhead_time(ra, dec, v.ra, v.dec, config.slew, change)  # from exposure a to the visit
    out_of = overhead_time(v.ra, v.dec, ra, dec, config.slew, change)  # from the visit to exposure b
    # gap i sits after exposure i (i = n - 1: after the last one); inserting at index i + 1
    ready = end + into
    latest_end = np.append(start[1:] - out_of[1:], config.horizon_s)
    for i in np.flatnonzero(latest_end - np.maximum(ready, v.due_s) >= exp):
        s = _earliest_for(v, max(float(ready[i]), v.due_s), exp, windows)
        if s is not None and s + exp <= latest_end[i]:
            return int(i) + 1, float(s)
    return None


def drop_repeats(observations: Sequence[Observation], visits: Sequence[PendingVisit]
                 ) -> tuple[tuple[Observation, ...], tuple[int, ...]]:
    """Remove the repeat of the done filter from half-done fields planned as whole pairs (P6).

    A field with a pending visit ``v`` that the plan observes in both
    filters loses its exposure in the filter already done when the plan's
    exposure in ``v.filter`` starts at or after ``v.due_s``: the executed
    exposure and that one are the pair.  Removing an exposure never breaks
    the plan's overheads (a slew is shorter than two, the filter change at
    most one of them).

    Returns
    -------
    observations : tuple of Observation
        The plan without the repeats.
    fields : tuple of int
        The fields whose repeat was removed.
    """
    by_field = {v.field_id: v for v in visits}
    drop: set[int] = set()
    fields: list[int] = []
    for fid, v in by_field.items():
        mine = [i for i, o in enumerate(observations) if o.field_id == fid]
        other = [i for i in mine if observations[i].filter == v.filter
                 and v.due_s <= observations[i].start <= v.latest_s]  # (P10) still a pair with the done one
        repeat = [i for i in mine if observations[i].filter != v.filter]
        if other and repeat:
            drop.update(repeat)
            fields.append(fid)
    return tuple(o for i, o in enumerate(observations) if i not in drop), tuple(fields)
