"""The checker's rules for a filter sequence other than a pair (F6-F8, ``docs/design/sequences.md``).

Written apart from the schedulers and from :mod:`..sequences` (the
planner's F1-F3): the checker reads the plan and the executed record on
their own.

* (F6) a field without covering executed exposures is planned in the whole
  sequence, or in a prefix of it holding its first two visits: (F10) in a
  plan, only where no window holds its next visit (``clear`` finds none
  from a cadence after its last visit to the separation after its first);
  (F9) in a re-plan (with an executed record), as the re-plan's shift
  left it: its exposures, in time order, are ``filters`` or such a prefix,
  each at least ``cadence_s`` after the one before, the last at most
  ``pair_separation_s`` after the first;
* (F7) a field the executed record covers (the pair rule on the first two
  filters, or one exposure for a one-filter sequence) is planned only in a
  continuation: its exposures are ``filters[j:j + m]`` for some ``j >= 2``,
  the first at least the cadence after a done exposure in ``filters[j-1]``,
  each later one the cadence after the one before, all within the
  separation of the field's earliest done exposure;
* (F8) a continuation does not repeat a visit: no done exposure in
  ``filters[j]`` lies the cadence after a done one in ``filters[j-1]``.

Times are seconds since the plan's start; done exposures are negative
before it.
"""

from __future__ import annotations

from typing import Callable, Mapping, Optional, Sequence

import numpy as np

__all__ = ["check_sequences", "covered_by_record", "NextVisitClear"]

#: ``clear(fields, filters, after, until) -> starts``: for each cut sequence, the first start (s) in
#: ``[after, until]`` at which its field's next visit (in that filter) is clearly observable, NaN where none is.
NextVisitClear = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]

#: Slack (s) on every time comparison, as the checker's.
TOL_S = 1e-3


def covered_by_record(done: Mapping[int, Mapping[str, np.ndarray]], filters: Sequence[str],
                      cadence_s: float, separation_s: float) -> dict[int, tuple[float, float]]:
    """The fields a record covers, each with its covering pair's (earlier, later) exposure starts (s).

    Covering: an ``s_1`` and an ``s_2`` exposure ``[cadence, separation]``
    apart, either order (one ``s_1`` exposure for ``k = 1``); the pair is
    the one completed first (of those, the one started last).  ``done``:
    field -> filter -> done exposures' starts (s).
    """
    out: dict[int, tuple[float, float]] = {}
    for fid, per in done.items():
        a = per.get(filters[0], np.zeros(0))
        if len(filters) == 1:
            if a.size:
                out[int(fid)] = (float(a.min()), float(a.min()))
            continue
        b = per.get(filters[1], np.zeros(0))
        gaps = np.abs(a[:, None] - b[None, :])
        ok = (gaps >= cadence_s - TOL_S) & (gaps <= separation_s + TOL_S)
        if ok.any():
            later = np.maximum(a[:, None], b[None, :])
            t = float(later[ok].min())
            out[int(fid)] = (float(np.minimum(a[:, None], b[None, :])[ok & (later == t)].max()), t)
    return out


def check_sequences(add: Callable[[str, str], None], ids: np.ndarray, flt: np.ndarray, start: np.ndarray,
                    filters: Sequence[str], cadence_s: float, separation_s: float,
                    done: Mapping[int, Mapping[str, np.ndarray]], clear: Optional[NextVisitClear] = None) -> None:
    """F6-F8 (and F10) for each planned field; ``add(kind, text)`` records a problem.

    Parameters
    ----------
    add : callable
        The checker's problem list.
    ids, flt, start : numpy.ndarray
        The plan's exposures (field, filter, start in s), any order.
    filters : sequence of str
        The sequence.
    cadence_s, separation_s : float
        Least time between consecutive visits, most from first to last (s).
    done : mapping
        Field -> filter -> done executed exposures' starts (s), empty without a record.
    clear : callable, optional
        (F10) where a cut sequence's next visit could have been taken (:data:`NextVisitClear`); None: cuts
        are not checked against the sky.
    """
    seq = tuple(filters)
    covered = covered_by_record(done, seq, cadence_s, separation_s)
    cut: list[tuple[int, str, float, float]] = []
    for fid in np.unique(ids):
        sel = np.flatnonzero(ids == fid)
        order = sel[np.argsort(start[sel], kind="stable")]
        bands, times = tuple(flt[order].tolist()), start[order]
        short = np.flatnonzero(np.diff(times) < cadence_s - TOL_S)
        if short.size:
            i = int(short[0])
            add("cadence", f"field {fid}: {bands[i]} and {bands[i + 1]} only {times[i + 1] - times[i]:.0f} s apart "
                           f"(cadence {cadence_s:.0f} s)")
        if int(fid) not in covered:  # (F6) the whole sequence; (F10, F9) or its first two visits on
            if bands != seq and not (bands == seq[:len(bands)] and len(bands) >= min(2, len(seq))):
                add("cadence", f"field {fid} is observed in {'-'.join(bands)}, not the sequence {'-'.join(seq)}"
                               " nor its first two visits or more")
            elif times[-1] - times[0] > separation_s + TOL_S:
                add("cadence", f"field {fid}: its sequence spans {times[-1] - times[0]:.0f} s, more than "
                               f"{separation_s:.0f} s")
            elif bands != seq and not done:
                cut.append((int(fid), seq[len(bands)], float(times[-1]) + cadence_s, float(times[0]) + separation_s))
            continue
        _check_continuation(add, int(fid), bands, times, seq, cadence_s, separation_s, done[int(fid)],
                            covered[int(fid)])
    if cut and clear is not None:
        _check_cuts(add, cut, seq, clear)


def _check_cuts(add: Callable[[str, str], None], cut: list[tuple[int, str, float, float]], seq: tuple[str, ...],
                clear: NextVisitClear) -> None:
    """(F10) a sequence cut short in a plan: its next visit had no window from a cadence after its last visit to
    the separation after its first."""
    fields, bands, after, until = (np.array(c) for c in zip(*cut))
    starts = clear(fields, bands, after.astype(float), until.astype(float))
    for fid, band, t in zip(fields, bands, starts):
        if np.isfinite(t):
            add("cadence", f"field {fid} stops short of the sequence {'-'.join(seq)}, though its next visit "
                           f"({band}) could start at {t:.0f} s (F10)")


def _check_continuation(add: Callable[[str, str], None], fid: int, bands: tuple[str, ...], times: np.ndarray,
                        seq: tuple[str, ...], cadence_s: float, separation_s: float,
                        done: Mapping[str, np.ndarray], pair: tuple[float, float]) -> None:
    """(F7, F8) a covered field's planned exposures continue its sequence without repeating a visit.

    ``pair``: its covering pair's starts (s); visits ``j >= 3`` count only
    after it, and the separation runs from its earlier exposure.
    """
    earliest, paired = pair
    m = len(bands)
    starts = [j for j in range(2, len(seq) - m + 1) if seq[j:j + m] == bands]
    if not starts:
        add("repeat", f"field {fid} is covered (executed) and planned in {'-'.join(bands)}, not a continuation of "
                      f"{'-'.join(seq)}")
        return
    empty = np.zeros(0)
    for j in starts:
        before, again = done.get(seq[j - 1], empty), done.get(seq[j], empty)
        before = before[before >= paired - TOL_S] if j > 2 else np.append(before[before >= paired - TOL_S], paired)
        follows = (before <= times[0] - cadence_s + TOL_S).any()
        repeated = (again[:, None] >= before[None, :] + cadence_s - TOL_S).any()
        if follows and not repeated and times[-1] - earliest <= separation_s + TOL_S:
            return
    add("repeat", f"field {fid}: planned {'-'.join(bands)} does not follow its executed visits of "
                  f"{'-'.join(seq)} a cadence apart within {separation_s:.0f} s, or repeats one")
