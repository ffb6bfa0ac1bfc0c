"""Filter sequences: what a field's visits must be, and what a field's done visits are worth (F1-F4).

``[scheduler] filters`` is the sequence ``S = (s_1, ..., s_k)`` of filters each
planned field is visited in, in that order, each visit at least ``cadence_s``
after the field's previous one and all of them within one night
(``pair_separation_s``): ``("g", "r")`` is the pair the schedulers were built
for, ``("g", "r", "g")`` what ZTF's GW programme ran in O4
(``docs/design/sequences.md``).

* (F1) a field is *covered* (its probability counts) once it has an ``s_1``
  and an ``s_2`` exposure at least the cadence and at most the pair
  separation apart, in either order -- the pair rule E3 of the first two
  filters; with ``k = 1`` one exposure in ``s_1``.  Later visits add
  nothing to coverage: they are what the team runs (colour and fading);
* (F2) a covered field's *progress* ``n`` counts its visits in sequence
  order: 2 for the covering pair (the earliest-completed one), then each
  later done exposure in ``s_{n+1}`` at least the cadence after the last
  counted one and within the separation of the first; the field is
  *complete* when ``n = k``;
* (F3) a re-plan gives a covered, incomplete field its next visit
  ``s_{n+1}`` a cadence after the last counted one (a pending visit, kept
  whatever it adds); a field with done exposures but not covered is planned
  as a whole new sequence when ``k != 2`` (the pair keeps P2: its other
  filter);
* (F4) the slot MILP plans any sequence of two or more (S4-S6); the
  schedulers that model a field as exactly two exposures (the block MILP,
  the exact model, the LNS, the detection stage) refuse a sequence of
  another length (:func:`require_pair`); the hybrid skips them and says so.

Pure: no I/O, no globals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

from astropy.time import Time

from .errors import InputError
from .executed import MIN_PROCESSED_FRACTION, DonePairs, ExecutedExposure, FieldVisits, done_pairs, is_done

__all__ = ["SequenceProgress", "is_pair", "require_pair", "done_covering", "covered_fields",
           "sequence_progress"]

@dataclass(frozen=True)
class SequenceProgress:
    """How far a covered field got through the sequence (F2).

    Attributes
    ----------
    field_id : int
        ZTF field ID.
    done : int
        Visits counted, ``2 <= done <= k`` (``1`` for ``k = 1``).
    first : astropy.time.Time
        Start (UTC) of the covering pair's earlier exposure.
    last : astropy.time.Time
        Start (UTC) of the last counted visit: the next is due a cadence after it.
    """

    field_id: int
    done: int
    first: Time
    last: Time


def is_pair(filters: Sequence[str]) -> bool:
    """True for a sequence of two filters (what every scheduler plans)."""
    return len(tuple(filters)) == 2


def require_pair(filters: Sequence[str], scheduler: str, longer: bool = False) -> None:
    """(F4) Refuse a sequence a scheduler does not model: other than a pair, or (``longer``) shorter than one.

    ``longer``: the scheduler plans any sequence of ``k >= 2`` visits (the
    slot MILP, S4-S6); else only the pair.

    Raises
    ------
    InputError
        One line naming the scheduler, the sequence and what to use instead.
    """
    k = len(tuple(filters))
    if k == 2 or (longer and k > 2):
        return
    what = "a sequence of two or more filters" if longer else "each field in two filters"
    raise InputError(f"the {scheduler} plans {what}; [scheduler] filters = {list(filters)!r} is a sequence "
                     f"of {k}: use solver greedy or hybrid")


def _done_by_field(exposures: Iterable[ExecutedExposure], filters: Sequence[str],
                   min_processed_fraction: float) -> dict[int, list[tuple[float, str, Time]]]:
    """Field -> its done exposures in the sequence's filters as (unix, filter, start), in time order."""
    out: dict[int, list[tuple[float, str, Time]]] = {}
    for e in exposures:
        if e.filter in filters and is_done(e, min_processed_fraction):
            out.setdefault(int(e.field_id), []).append((float(e.start.unix), e.filter, e.start))
    return {f: sorted(v, key=lambda x: (x[0], x[1])) for f, v in out.items()}


def covered_fields(exposures: Iterable[ExecutedExposure], filters: Sequence[str],
                   min_processed_fraction: float = MIN_PROCESSED_FRACTION, cadence_s: float = 0.0,
                   max_separation_s: float = math.inf) -> set[int]:
    """(F1) The fields the record covers: E3 on the sequence's first two filters, or one visit for ``k = 1``.

    Parameters
    ----------
    exposures : iterable of ExecutedExposure
        The record (only done exposures, E1, count).
    filters : sequence of str
        The sequence ``S``.
    min_processed_fraction : float
        The done rule's threshold (0-1).
    cadence_s, max_separation_s : float
        Least and most time (s) between the covering pair's two exposures.
    """
    return set(done_covering(exposures, filters, min_processed_fraction, cadence_s, max_separation_s).both)


def done_covering(exposures: Iterable[ExecutedExposure], filters: Sequence[str],
                  min_processed_fraction: float = MIN_PROCESSED_FRACTION, cadence_s: float = 0.0,
                  max_separation_s: float = math.inf) -> DonePairs:
    """(F1) :func:`~.executed.done_pairs` of a sequence: ``both`` the covered fields, ``one`` the others with a done visit.

    The pair rule (E3) on the sequence's first two filters; a one-filter
    sequence covers a field with one done exposure (``one`` is then empty).
    """
    seq = tuple(filters)
    if len(seq) >= 2:
        return done_pairs(exposures, (seq[0], seq[1]), min_processed_fraction, cadence_s, max_separation_s)
    both = {f: FieldVisits(f, {seq[0]: v[0][2]}) for f, v in _done_by_field(exposures, seq, min_processed_fraction).items()}
    return DonePairs(seq, both, {})  # type: ignore[arg-type]


def _covering_pair(visits: list[tuple[float, str, Time]], a: str, b: str, cadence_s: float,
                   max_separation_s: float) -> tuple[int, int] | None:
    """Indices (earlier, later) of the covering pair completed first (F2), None when there is none."""
    best: tuple[float, float, int, int] | None = None
    for i, (ti, fi, _) in enumerate(visits):
        for j in range(i + 1, len(visits)):
            tj, fj, _ = visits[j]
            if {fi, fj} != {a, b} or not cadence_s <= tj - ti <= max_separation_s:
                continue
            key = (tj, -ti, i, j)
            if best is None or key < best:
                best = key
    return None if best is None else (best[2], best[3])


def sequence_progress(exposures: Iterable[ExecutedExposure], filters: Sequence[str],
                      min_processed_fraction: float = MIN_PROCESSED_FRACTION, cadence_s: float = 0.0,
                      max_separation_s: float = math.inf) -> dict[int, SequenceProgress]:
    """(F2) The covered fields' progress through the sequence.

    Parameters
    ----------
    exposures : iterable of ExecutedExposure
        The record (any order, duplicates allowed; only done exposures count).
    filters : sequence of str
        The sequence ``S``.
    min_processed_fraction : float
        The done rule's threshold (0-1).
    cadence_s, max_separation_s : float
        Least time (s) between consecutive counted visits, most time (s)
        from the first counted visit to any later one.

    Returns
    -------
    dict of int to SequenceProgress
        One entry per covered field (F1), none for the others.

    Examples
    --------
    A field done in g and r (35 min apart) of g,r,g with a 30 min cadence is
    covered with its third visit to do; a g 10 min later does not count:

    >>> from astropy.time import Time, TimeDelta
    >>> t0 = Time("2026-05-01T04:00:00", scale="utc")
    >>> done = [ExecutedExposure(700, f, t0 + TimeDelta(m * 60, format="sec"), 180.0, 1.0, "processed")
    ...         for f, m in (("g", 0), ("r", 35), ("g", 45))]
    >>> p = sequence_progress(done, ("g", "r", "g"), cadence_s=1800.0)[700]
    >>> p.done, p.last.isot
    (2, '2026-05-01T04:35:00.000')
    """
    seq = tuple(filters)
    out: dict[int, SequenceProgress] = {}
    for field_id, visits in _done_by_field(exposures, seq, min_processed_fraction).items():
        if len(seq) == 1:
            out[field_id] = SequenceProgress(field_id, 1, visits[0][2], visits[0][2])
            continue
        pair = _covering_pair(visits, seq[0], seq[1], cadence_s, max_separation_s)
        if pair is None:
            continue
        first, last = visits[pair[0]][0], visits[pair[1]][0]
        n, last_time = 2, visits[pair[1]][2]
        for t, f, start in visits[pair[1] + 1:]:
            if n < len(seq) and f == seq[n] and t - last >= cadence_s and t - first <= max_separation_s:
                n, last, last_time = n + 1, t, start
        out[field_id] = SequenceProgress(field_id, n, visits[pair[0]][2], last_time)
    return out
