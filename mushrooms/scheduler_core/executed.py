"""What the telescope did: the executed-exposure record and the rules a re-planner reads from it.

One :class:`ExecutedExposure` per ZTF exposure, whatever told us about it
(ZTF's depot, SkyPortal, a JSON-lines file, the loop benchmark's queue
simulator); the readers live in :mod:`mushrooms.handlers.executed`, the
simulator in :mod:`mushrooms.evaluation.queue_sim`.  The record, the done
rule (E1), the identity of an exposure (E2) and the line form of a JSON-lines
file are in ``docs/design/executed.md``.

Pure: no I/O, no globals.  Times are absolute astropy times (UTC): executed
exposures belong to no plan, so the plan's "seconds since start" would not
do; :func:`done_pairs` and the queue simulator turn them into numbers where
they compute.

The default least processed fraction, 0.5, is growth-too-marshal's rule: a
ZTF exposure counts towards the previous coverage when at least 32 of its 64
readout quadrants were processed (``growth-astro/growth-too-marshal``,
``growth/too/tasks/tiles.py``, ``idx = idx[cnts >= 32]``, commit cb511e8,
MIT licence).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
from astropy.time import Time, TimeDelta

from .errors import InputError

__all__ = [
    "ExecutedExposure", "FieldVisits", "DonePairs", "FILTERS", "STATUSES", "RECORD_KEYS",
    "N_QUADRANTS", "MIN_PROCESSED_FRACTION", "SAME_START_S", "FIELD_ID_MAX",
    "checked_values", "TelescopeExposure", "FILTER_NAME", "is_done", "counted_for_night", "same_exposure", "unique_exposures", "done_pairs", "to_record", "from_record",
]

#: The ZTF filters a record may name.
FILTERS = ("g", "r", "i")
#: What another telescope's filter name may be (:class:`TelescopeExposure`).
FILTER_NAME = re.compile(r"[A-Za-z0-9_.+-]{1,16}")
#: ``processed``: the exposure was taken and some of it reduced (how much: ``processed_fraction``);
#: ``failed``: taken, nothing reduced; ``aborted``: cut short (a weather closure in the simulator).
STATUSES = ("processed", "failed", "aborted")
#: The keys of a record's JSON form, in the order written (one JSON-lines line).
RECORD_KEYS = ("field_id", "filter", "start", "exposure_s", "processed_fraction", "status")
#: Readout quadrants of the ZTF camera (16 CCDs x 4).
N_QUADRANTS = 64
#: Default least processed fraction for an exposure to be done (E1): 32 of 64 quadrants.
MIN_PROCESSED_FRACTION = 0.5
#: Two records of one field and filter starting less than this apart (s) are the same exposure (E2).
SAME_START_S = 1.0
#: Longest exposure a record may claim (s): a day.
_MAX_EXPOSURE_S = 86400.0
#: (E0) The largest ZTF field id a record may carry: field ids are six-digit numbers (``ZTF_Fields.txt``
#: writes them ``%06d``; grids 1-4 use 1-3893).  A larger one is not a ZTF field (and would not fit
#: SQLite's 64-bit integers past 2^63): the record is skipped.
FIELD_ID_MAX = 999_999


@dataclass(frozen=True)
class ExecutedExposure:
    """One exposure ZTF took (or tried to take).

    Attributes
    ----------
    field_id : int
        ZTF field ID (positive).
    filter : str
        ``g``, ``r`` or ``i``.
    start : astropy.time.Time
        Exposure start (UTC, a scalar time; stored in the UTC scale).
    exposure_s : float
        Exposure time (s), in (0, 86400].
    processed_fraction : float
        Fraction of the 64 readout quadrants the pipeline reduced, in [0, 1].
    status : str
        One of :data:`STATUSES`.

    Raises
    ------
    InputError
        One line naming the bad attribute, when a value is out of its range.
    """

    field_id: int
    filter: str
    start: Time
    exposure_s: float
    processed_fraction: float
    status: str

    def __post_init__(self) -> None:
        self._normalise(FILTERS)

    def _normalise(self, filters: Sequence[str]) -> None:
        field_id, exposure, fraction = checked_values(self.field_id, self.filter, self.exposure_s,
                                                      self.processed_fraction, self.status, filters)
        if not isinstance(self.start, Time) or not self.start.isscalar:
            raise InputError(f"start {self.start!r}: not a scalar astropy Time")
        object.__setattr__(self, "field_id", field_id)
        object.__setattr__(self, "start", self.start.utc)
        object.__setattr__(self, "exposure_s", exposure)
        object.__setattr__(self, "processed_fraction", fraction)

    @property
    def end(self) -> Time:
        """Exposure end (UTC)."""
        return self.start + TimeDelta(self.exposure_s, format="sec")


@dataclass(frozen=True)
class TelescopeExposure(ExecutedExposure):
    """An exposure of another telescope than ZTF (issue 53): its filter any name of :data:`FILTER_NAME`.

    The reader checks it against the telescope's own filters
    (:func:`from_record` ``filters``); everything else as :class:`ExecutedExposure`.
    """

    def __post_init__(self) -> None:
        if not isinstance(self.filter, str) or not FILTER_NAME.fullmatch(self.filter):
            raise InputError(f"filter {str(self.filter)[:40]!r}: not a filter name (1-16 of A-Z a-z 0-9 _ . + -)")
        self._normalise((self.filter,))


def checked_values(field_id: Any, filter: Any, exposure_s: Any, processed_fraction: Any,
                   status: Any, filters: Sequence[str] = FILTERS) -> tuple[int, float, float]:
    """The checks of a record's values but its start: cheap, so a reader runs them before it parses the time.

    A record of the wrong type is refused here without the astropy time parse (a few hundred
    microseconds) its ``start`` would cost; :class:`ExecutedExposure` runs them too.

    Returns
    -------
    tuple of (int, float, float)
        ``field_id``, ``exposure_s`` (s) and ``processed_fraction`` as stored.

    Raises
    ------
    InputError
        One line naming the first bad value (in the order of the parameters).
    """
    if isinstance(field_id, bool) or not isinstance(field_id, (int, np.integer)) or field_id < 1:
        raise InputError(f"field_id {field_id!r}: not a positive integer")
    if field_id > FIELD_ID_MAX:
        raise InputError(f"field_id {str(field_id)[:24]}: not a ZTF field (at most {FIELD_ID_MAX})")
    if not isinstance(filter, str) or filter not in filters:
        raise InputError(f"filter {filter!r}: not one of {', '.join(filters)}")
    exposure = _number(exposure_s, "exposure_s")
    if not 0.0 < exposure <= _MAX_EXPOSURE_S:
        raise InputError(f"exposure_s {exposure_s!r}: not in (0, {_MAX_EXPOSURE_S:g}] s")
    fraction = _number(processed_fraction, "processed_fraction")
    if not 0.0 <= fraction <= 1.0:
        raise InputError(f"processed_fraction {processed_fraction!r}: not in [0, 1]")
    if not isinstance(status, str) or status not in STATUSES:
        raise InputError(f"status {status!r}: not one of {', '.join(STATUSES)}")
    return int(field_id), exposure, fraction


def _number(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} {value!r}: not a number")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(f"{name} {value!r}: not a finite number")
    return out


def is_done(exposure: ExecutedExposure, min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> bool:
    """Whether an exposure counts as observed (E1).

    Parameters
    ----------
    exposure : ExecutedExposure
        The record.
    min_processed_fraction : float
        Least fraction (0-1) of the 64 quadrants processed; default 0.5
        (growth-too-marshal's 32 of 64).

    Returns
    -------
    bool
        ``status == "processed"`` and ``processed_fraction >= min_processed_fraction``.
    """
    if not 0.0 <= min_processed_fraction <= 1.0:
        raise ValueError(f"min_processed_fraction must be in [0, 1], got {min_processed_fraction}")
    return exposure.status == "processed" and exposure.processed_fraction >= min_processed_fraction


def same_exposure(a: ExecutedExposure, b: ExecutedExposure, tolerance_s: float = SAME_START_S) -> bool:
    """Whether two records describe one exposure (E2): same field, same filter, starts less than ``tolerance_s`` (s) apart."""
    return (a.field_id == b.field_id and a.filter == b.filter
            and abs((a.start - b.start).to_value("s")) < tolerance_s)


def unique_exposures(exposures: Iterable[ExecutedExposure],
                     tolerance_s: float = SAME_START_S) -> tuple[ExecutedExposure, ...]:
    """The records with duplicates (E2) collapsed, in start order.

    Of the records of one exposure the one with the largest processed
    fraction stays (a later report of the same exposure has seen more of
    the pipeline), the first of them on a tie.

    Parameters
    ----------
    exposures : iterable of ExecutedExposure
        Records, in any order, possibly from several sources.
    tolerance_s : float
        Starts (s) closer than this are one exposure (default 1 s; ZTF's
        exposures last at least 30 s, so two real ones never come closer).

    Returns
    -------
    tuple of ExecutedExposure
        Sorted by (start, field, filter).
    """
    items = list(exposures)
    if not items:
        return ()
    t = Time([e.start for e in items]).unix if len(items) > 1 else np.array([items[0].start.unix])
    order = sorted(range(len(items)), key=lambda k: (items[k].field_id, items[k].filter, t[k], k))
    kept: list[int] = []
    for k in order:
        last = kept[-1] if kept else None
        if (last is not None and items[last].field_id == items[k].field_id
                and items[last].filter == items[k].filter and t[k] - t[last] < tolerance_s):
            if items[k].processed_fraction > items[last].processed_fraction:
                kept[-1] = k
            continue
        kept.append(k)
    kept.sort(key=lambda k: (t[k], items[k].field_id, items[k].filter))
    return tuple(items[k] for k in kept)


@dataclass(frozen=True)
class FieldVisits:
    """The done exposures of one field, per filter.

    Attributes
    ----------
    field_id : int
        ZTF field ID.
    first : Mapping[str, astropy.time.Time]
        Filter -> start (UTC) of the field's first done exposure in it.
    """

    field_id: int
    first: Mapping[str, Time]

    @property
    def filters(self) -> tuple[str, ...]:
        """The filters done, in the order they were first done."""
        return tuple(sorted(self.first, key=lambda f: self.first[f].unix))

    @property
    def earliest(self) -> Time:
        """Start (UTC) of the field's first done exposure."""
        return self.first[self.filters[0]]


@dataclass(frozen=True)
class DonePairs:
    """Which fields are done in both filters of the pair, which in one only.

    Attributes
    ----------
    filters : tuple of str
        The pair (the plan's two filters, e.g. ``("g", "r")``).
    both : Mapping[int, FieldVisits]
        Fields done in both filters (at least ``cadence_s`` apart).
    one : Mapping[int, FieldVisits]
        Fields done in one filter only, or in both too close together;
        ``visits.filters[0]`` and ``visits.earliest`` say which filter first and
        when, so a re-planner can plan the other filter a cadence later.
    """

    filters: tuple[str, str]
    both: Mapping[int, FieldVisits]
    one: Mapping[int, FieldVisits]


def done_pairs(exposures: Iterable[ExecutedExposure], filters: tuple[str, str] = ("g", "r"),
               min_processed_fraction: float = MIN_PROCESSED_FRACTION, cadence_s: float = 0.0,
               max_separation_s: float = math.inf) -> DonePairs:
    """Fields done in both filters of a pair, and fields done in one (E3).

    Parameters
    ----------
    exposures : iterable of ExecutedExposure
        Records (duplicates and other filters allowed: only done exposures
        (E1) in one of ``filters`` count).
    filters : tuple of str
        The two filters, e.g. ``PlanningConfig.filters``.
    min_processed_fraction : float
        The done rule's threshold (0-1), see :func:`is_done`.
    cadence_s : float
        Least time (s) between the two filters' exposures for the pair to
        count (``PlanningConfig.cadence_s``); 0 takes any two.
    max_separation_s : float
        (P10) Most time (s) between them (``PlanningConfig.pair_separation_s``):
        a pair counts only with an ``a`` and a ``b`` exposure separated by
        ``[cadence_s, max_separation_s]``; default any.

    Returns
    -------
    DonePairs
        Each field in at most one of ``both`` and ``one``.
    """
    a, b = filters
    if a == b or not isinstance(a, str) or not isinstance(b, str):  # any telescope's filters (its description's)
        raise ValueError(f"filters must be two different filter names, got {filters!r}")
    if cadence_s < 0:
        raise ValueError(f"cadence_s must be >= 0, got {cadence_s}")
    starts: dict[int, dict[str, list[tuple[float, Time]]]] = {}
    for e in exposures:
        if e.filter in filters and is_done(e, min_processed_fraction):
            starts.setdefault(e.field_id, {}).setdefault(e.filter, []).append((e.start.unix, e.start))
    both: dict[int, FieldVisits] = {}
    one: dict[int, FieldVisits] = {}
    for field_id in sorted(starts):
        per = starts[field_id]
        visits = FieldVisits(field_id, {f: min(v, key=lambda x: x[0])[1] for f, v in per.items()})
        if len(per) == 2:
            gaps = np.abs(np.array([x[0] for x in per[a]])[:, None] - np.array([x[0] for x in per[b]])[None, :])
            # (E3) an a and a b exposure at least the cadence apart, (P10) and at most the largest separation
            if ((gaps >= cadence_s) & (gaps <= max_separation_s)).any():
                both[field_id] = visits
                continue
        one[field_id] = visits
    return DonePairs((a, b), both, one)


def counted_for_night(done: Sequence[ExecutedExposure], evening: Time, revisit: bool) -> list[ExecutedExposure]:
    """What a night's plan counts as done: (N2) everything before it, or (N4) with ``revisit`` only its own night's.

    Parameters
    ----------
    done : sequence of ExecutedExposure
        Executed exposures and the earlier nights' plans taken as done.
    evening : astropy.time.Time
        The night's start ``s_n`` (its evening twilight, or the start when the night is under way).
    revisit : bool
        ``[scheduler] revisit``: the earlier nights' fields may be observed again.

    Returns
    -------
    list of ExecutedExposure
        ``done`` (N2), or the exposures of ``done`` starting at or after ``evening`` (N4).
    """
    if not revisit:
        return list(done)
    cut = float(Time(evening, scale="utc").unix)
    return [e for e in done if float(e.start.unix) >= cut]


def to_record(exposure: ExecutedExposure) -> dict[str, Any]:
    """The record's JSON form (one JSON-lines line): :data:`RECORD_KEYS`, ``start`` ISO-8601 UTC to the millisecond with ``Z``."""
    from .times import iso_utc

    return {
        "field_id": exposure.field_id,
        "filter": exposure.filter,
        "start": iso_utc(exposure.start),
        "exposure_s": exposure.exposure_s,
        "processed_fraction": exposure.processed_fraction,
        "status": exposure.status,
    }


def from_record(record: Mapping[str, Any], filters: Sequence[str] = FILTERS) -> ExecutedExposure:
    """A record from its JSON form (exactly :data:`RECORD_KEYS`).

    ``filters``: the telescope's (default ZTF's g, r, i); a record of a filter
    outside ZTF's is a :class:`TelescopeExposure`.

    Raises
    ------
    InputError
        One line: a missing or unknown key, or a value out of its range.
    """
    from .times import parse_time

    if not isinstance(record, Mapping):
        raise InputError(f"a {type(record).__name__}, not a JSON object")
    missing = [k for k in RECORD_KEYS if k not in record]
    if missing:
        raise InputError(f"missing key(s) {', '.join(missing)}")
    unknown = sorted(str(k) for k in record if k not in RECORD_KEYS)
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)}")
    if not isinstance(record["start"], str):
        raise InputError(f"start {record['start']!r}: not an ISO-8601 string")
    # the cheap checks first: a record of the wrong type costs no time parse
    checked_values(record["field_id"], record["filter"], record["exposure_s"], record["processed_fraction"],
                   record["status"], filters)
    return (ExecutedExposure if record["filter"] in FILTERS else TelescopeExposure)(
        field_id=record["field_id"],
        filter=record["filter"],
        start=parse_time(record["start"], "start"),
        exposure_s=record["exposure_s"],
        processed_fraction=record["processed_fraction"],
        status=record["status"],
    )
