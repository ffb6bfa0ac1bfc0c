"""Readers of what ZTF executed, one per source, all to :class:`~mushrooms.scheduler_core.executed.ExecutedExposure`.

Sources (``docs/design/executed.md`` has the field mapping and its sources):

* ZTF's depot, ``<depot>/<YYYYMMDD>/ztf_recentproc_<YYYYMMDD>.json``
  (:func:`read_depot`): one row per readout quadrant, grouped by exposure;
* SkyPortal's ``GET /api/observation`` answer (:func:`read_skyportal`);
* a JSON-lines file, one record per line with exactly the record's keys
  (:func:`read_jsonl`, :func:`write_jsonl`): what tests and operators write.

Each reader takes the content (``bytes`` or ``str``: the text itself) or a
file (a :class:`pathlib.Path`; :func:`read_jsonl` also an open binary file,
which it streams: a file of any size costs one line of memory, and a line
longer than :data:`MAX_LINE_BYTES` is skipped unread); none fetches
anything (the daemon does).  A
malformed record is skipped with one warning line on this module's logger
naming where it is and what is wrong, and the rest is kept; content that is
not what the source sends at all (not JSON, not a list) raises
:class:`~mushrooms.scheduler_core.errors.InputError` with one line.
Duplicates (E2) collapse to one record; the result is in start order.

Facts (field names, codes) come from SkyPortal (``skyportal/skyportal``,
commit 8bd346c, BSD-3-Clause licence): ``skyportal/facility_apis/ztf.py``
(``fetch_depot_observations``: the depot URL, ``status == 0`` for a reduced
quadrant, ``processed_fraction`` = reduced quadrants / 64, filter ids
``{1: "ztfg", 2: "ztfr", 3: "ztfi"}``), ``skyportal/handlers/api/observation.py``
(``get_observations``: ``data.observations[]``, each the
``ExecutedObservation`` row's columns plus its ``field``) and
``skyportal/models/observation.py`` (``obstime``, ``filt``,
``exposure_time``, ``processed_fraction``).  No code is taken from it.
"""

from __future__ import annotations

import io
import json
import logging
import math
import os
from pathlib import Path
from typing import Any, BinaryIO, Iterable, Iterator, Mapping, Sequence

import numpy as np
from astropy.time import Time

from ..scheduler_core.errors import InputError
from ..scheduler_core.executed import (
    FILTERS, N_QUADRANTS, ExecutedExposure, checked_values, from_record, to_record, unique_exposures,
)
from ..scheduler_core.times import parse_time
from .executed_source import SOURCE_KINDS, ExecutedSource, parse_executed_source
from .text import storable

__all__ = [
    "ExecutedSource", "SOURCE_KINDS", "parse_executed_source", "read_depot", "read_skyportal",
    "read_jsonl", "write_jsonl", "depot_paths", "DEPOT_FILTERS", "SKYPORTAL_FILTERS",
]

log = logging.getLogger(__name__)

#: ZTF's filter ids as the depot writes them (SkyPortal's ``inv_bands`` without the ``ztf`` prefix).
DEPOT_FILTERS = {1: "g", 2: "r", 3: "i"}
#: SkyPortal's names of ZTF's filters (an executed observation's ``filt``).
SKYPORTAL_FILTERS = {"ztfg": "g", "ztfr": "r", "ztfi": "i"}
#: The depot's quadrant ``status`` of a successfully reduced quadrant.
DEPOT_STATUS_OK = 0
#: The keys a depot row must have.
_DEPOT_KEYS = ("exposure_id", "field_id", "filter_id", "obsjd", "exposure_time", "status")


def depot_paths(start: Time, end: Time) -> list[str]:
    """The depot files (relative to the depot) that may hold exposures between two times.

    As SkyPortal asks the depot: one ``YYYYMMDD/ztf_recentproc_YYYYMMDD.json``
    per Julian day from ``floor(jd_start)`` up to ``ceil(jd_end)`` (excluded),
    named by the UTC date of that day's noon.

    Parameters
    ----------
    start, end : astropy.time.Time
        The span (UTC), ``start <= end``.

    Returns
    -------
    list of str
    """
    jd0, jd1 = float(start.utc.jd), float(end.utc.jd)
    if jd1 < jd0:
        raise ValueError("start must not be after end")
    days = np.arange(math.floor(jd0), math.ceil(jd1))
    names = [Time(float(jd), format="jd", scale="utc").datetime.strftime("%Y%m%d") for jd in days]
    return [f"{d}/ztf_recentproc_{d}.json" for d in names]


# ------------------------------------------------------------------ reading helpers
def _text(source: bytes | str | os.PathLike, what: str) -> str:
    """The content: ``bytes``/``str`` are the text, a path is read."""
    if isinstance(source, os.PathLike):
        try:
            data = Path(source).read_bytes()
        except OSError as exc:
            raise InputError(f"{what}: cannot read {source}: {exc.strerror or exc}") from None
    elif isinstance(source, (bytes, bytearray)):
        data = bytes(source)
    elif isinstance(source, str):
        return source
    else:
        raise InputError(f"{what}: a {type(source).__name__}, not bytes, str or a path")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what}: not UTF-8 text (byte {exc.start})") from None


def _named(source: bytes | str | os.PathLike, what: str) -> str:
    """The source's name in messages: ``what`` and, for a file, its name."""
    return f"{what} {Path(source).name}" if isinstance(source, os.PathLike) else what


def _json(source: bytes | str | os.PathLike, what: str) -> Any:
    text = _text(source, what)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        hint = " (a str is the content; pass a pathlib.Path to read a file)" if isinstance(source, str) else ""
        raise InputError(f"{what}: not JSON: {exc.msg} at line {exc.lineno} column {exc.colno}{hint}") from None


def _integer(value: Any, name: str) -> int:
    """An integer (a float with no fraction too: pandas writes ids as floats)."""
    if isinstance(value, bool):
        raise InputError(f"{name} {value!r}: not an integer")
    if isinstance(value, int):
        return value
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        return int(value)
    raise InputError(f"{name} {value!r}: not an integer")


def _finite(value: Any, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{name} {value!r}: not a finite number")
    return float(value)


#: (L16) Malformed records logged one by one per read; the rest are counted in one line.
MAX_WARNINGS = 10


class _Skipped:
    """The malformed records of one read: the first :data:`MAX_WARNINGS` logged, the others counted."""

    def __init__(self, what: str) -> None:
        self.what, self.count = what, 0

    def __call__(self, where: str, problem: Any) -> None:
        self.count += 1
        if self.count <= MAX_WARNINGS:  # the problem quotes the record: one short line, no control character
            log.warning("%s %s: %s; skipped", self.what, where, storable(problem, 300))

    def done(self) -> None:
        if self.count > MAX_WARNINGS:
            log.warning("%s: %d more malformed record(s) skipped (%d in all; the first %d are listed)", self.what,
                        self.count - MAX_WARNINGS, self.count, MAX_WARNINGS)


def _status(fraction: float) -> str:
    """(E0) processed when some of the exposure was reduced, else failed."""
    return "processed" if fraction > 0 else "failed"


# ------------------------------------------------------------------ ZTF's depot
def _depot_rows(doc: Any, what: str) -> list[Any]:
    """The rows of a depot file: a list of objects, or (as pandas also reads it) an object of equal-length columns."""
    if isinstance(doc, list):
        return doc
    if isinstance(doc, dict) and doc and all(isinstance(v, list) for v in doc.values()):
        lengths = {len(v) for v in doc.values()}
        if len(lengths) != 1:
            raise InputError(f"{what}: columns of different lengths {sorted(lengths)}")
        n = lengths.pop()
        return [{k: v[i] for k, v in doc.items()} for i in range(n)]
    raise InputError(f"{what}: a JSON {type(doc).__name__}, not a list of quadrant rows")


def _depot_exposure_id(row: Any) -> int:
    """The ``exposure_id`` of a depot row whose every needed value is readable (else :class:`InputError`)."""
    if not isinstance(row, Mapping):
        raise InputError(f"a {type(row).__name__}, not an object")
    missing = [k for k in _DEPOT_KEYS if row.get(k) is None]
    if missing:
        raise InputError(f"missing {', '.join(missing)}")
    expid = _integer(row["exposure_id"], "exposure_id")
    filter_id = _integer(row["filter_id"], "filter_id")
    if filter_id not in DEPOT_FILTERS:
        raise InputError(f"filter_id {filter_id} is not 1, 2 or 3 (g, r, i)")
    _integer(row["field_id"], "field_id")
    _integer(row["status"], "status")
    _finite(row["obsjd"], "obsjd")
    _finite(row["exposure_time"], "exposure_time")
    return expid


def read_depot(source: bytes | str | os.PathLike, what: str = "depot file",
               program_ids: Iterable[int] = ()) -> tuple[ExecutedExposure, ...]:
    """Exposures of a ZTF depot ``ztf_recentproc_<YYYYMMDD>.json``.

    The file has one row per readout quadrant of an exposure with (among
    others) ``exposure_id``, ``field_id``, ``filter_id`` (1 g, 2 r, 3 i),
    ``obsjd`` (exposure start, JD UTC), ``exposure_time`` (s) and ``status``
    (0: the quadrant was reduced).  Rows are grouped by ``exposure_id``;
    each exposure takes its rows' median ``obsjd`` and ``exposure_time`` (as
    SkyPortal does), ``processed_fraction`` = reduced quadrants / 64 (distinct
    ``rcid`` when the rows have it, else rows; at most 1) and status (E0).
    Unlike SkyPortal, which keeps reduced quadrants only, an exposure with
    none reduced is kept, as ``failed`` with fraction 0.

    Parameters
    ----------
    source : bytes, str or path
        The file's content, or the file.
    what : str
        Name of the source in messages.
    program_ids : iterable of int
        (L18) Keep only rows whose ``programid`` is one of these (a row
        without one is of no programme and left out); empty: every row.

    Returns
    -------
    tuple of ExecutedExposure
        In start order.

    Raises
    ------
    InputError
        Not JSON, or not a list of rows.
    """
    what = _named(source, what)
    rows = _depot_rows(_json(source, what), what)
    wanted = set(program_ids)
    if wanted:
        rows = [r for r in rows if isinstance(r, Mapping) and r.get("programid") in wanted]
    groups: dict[int, list[tuple[int, Mapping[str, Any]]]] = {}
    skipped = _Skipped(what)
    for i, row in enumerate(rows):
        try:
            expid = _depot_exposure_id(row)
        except InputError as exc:
            skipped(f"row {i}", exc)
            continue
        groups.setdefault(expid, []).append((i, row))
    out = []
    for expid, members in groups.items():
        first = members[0][0]
        try:
            fields = {_integer(r["field_id"], "field_id") for _, r in members}
            filters = {_integer(r["filter_id"], "filter_id") for _, r in members}
            if len(fields) > 1 or len(filters) > 1:
                raise InputError(f"rows disagree on field_id {sorted(fields)} or filter_id {sorted(filters)}")
            ok = [r for _, r in members if _integer(r["status"], "status") == DEPOT_STATUS_OK]
            quadrants = ({r.get("rcid") for r in ok} if all("rcid" in r for r in ok) else range(len(ok)))
            fraction = min(1.0, len(quadrants) / N_QUADRANTS)
            jd = float(np.median([float(r["obsjd"]) for _, r in members]))
            values = (fields.pop(), DEPOT_FILTERS.get(filters.pop()),
                      float(np.median([float(r["exposure_time"]) for _, r in members])), fraction, _status(fraction))
            checked_values(*values)  # the cheap checks before the time is built
            out.append(ExecutedExposure(
                field_id=values[0], filter=values[1], start=parse_time(Time(jd, format="jd", scale="utc"), "obsjd"),
                exposure_s=values[2], processed_fraction=fraction, status=values[4],
            ))
        except InputError as exc:
            skipped(f"exposure_id {expid} (first row {first})", exc)
    skipped.done()
    return unique_exposures(out)


# ------------------------------------------------------------------ SkyPortal
def _skyportal_list(doc: Any, what: str) -> list[Any]:
    if isinstance(doc, dict) and doc.get("status") == "error":
        raise InputError(f"{what}: SkyPortal answered an error: {str(doc.get('message', ''))[:200]}")
    data = doc.get("data", doc) if isinstance(doc, dict) else None
    observations = data.get("observations") if isinstance(data, dict) else None
    if not isinstance(observations, list):
        raise InputError(f"{what}: no data.observations list (a GET /api/observation answer has one)")
    return observations


def read_skyportal(source: bytes | str | os.PathLike, what: str = "SkyPortal answer") -> tuple[ExecutedExposure, ...]:
    """Exposures of a SkyPortal ``GET /api/observation`` answer.

    ``{"status": "success", "data": {"observations": [...], "totalMatches": n}}``
    (the ``data`` block alone is accepted too).  Each observation is an
    ``ExecutedObservation``: ``obstime`` (exposure start, ISO-8601, naive
    UTC), ``filt`` (``ztfg``/``ztfr``/``ztfi``), ``exposure_time`` (s),
    ``processed_fraction`` (0-1) and ``field`` with the ZTF ``field_id``
    (the top-level ``instrument_field_id`` is SkyPortal's database key, not
    the ZTF field).  Status (E0).

    Parameters
    ----------
    source : bytes, str or path
        The answer's content, or a file holding it.
    what : str
        Name of the source in messages.

    Returns
    -------
    tuple of ExecutedExposure
        In start order.

    Raises
    ------
    InputError
        Not JSON, an error answer, or no ``data.observations`` list.
    """
    what = _named(source, what)
    out = []
    skipped = _Skipped(what)
    for i, obs in enumerate(_skyportal_list(_json(source, what), what)):
        try:
            if not isinstance(obs, Mapping):
                raise InputError(f"a {type(obs).__name__}, not an object")
            field = obs.get("field")
            if not isinstance(field, Mapping) or field.get("field_id") is None:
                raise InputError("no field.field_id")
            filt = obs.get("filt")
            if filt not in SKYPORTAL_FILTERS:
                raise InputError(f"filt {filt!r} is not ztfg, ztfr or ztfi")
            if not isinstance(obs.get("obstime"), str):
                raise InputError(f"obstime {obs.get('obstime')!r}: not an ISO-8601 string")
            fraction = _finite(obs.get("processed_fraction"), "processed_fraction")
            field_id = _integer(field["field_id"], "field.field_id")
            exposure = _finite(obs.get("exposure_time"), "exposure_time")
            checked_values(field_id, SKYPORTAL_FILTERS[filt], exposure, fraction, _status(fraction))  # before the time
            out.append(ExecutedExposure(
                field_id=field_id, filter=SKYPORTAL_FILTERS[filt], start=parse_time(obs["obstime"], "obstime"),
                exposure_s=exposure, processed_fraction=fraction, status=_status(fraction),
            ))
        except InputError as exc:
            skipped(f"observation {i}", exc)
    skipped.done()
    return unique_exposures(out)


# ------------------------------------------------------------------ JSON lines
#: Longest line of a JSON-lines file read (bytes): a record is about 150; a longer line is skipped unread.
MAX_LINE_BYTES = 64 * 1024


def _stream(fh: BinaryIO) -> Iterator[tuple[int, bytes | None]]:
    """(number from 1, line) of a binary file, one at a time; None for a line over :data:`MAX_LINE_BYTES`."""
    n = 0
    while True:
        line = fh.readline(MAX_LINE_BYTES + 1)
        if not line:
            return
        n += 1
        if len(line) > MAX_LINE_BYTES and not line.endswith(b"\n"):
            while line and not line.endswith(b"\n"):  # the rest of it, a bounded piece at a time
                line = fh.readline(MAX_LINE_BYTES)
            yield n, None
            continue
        yield n, line[3:] if n == 1 and line.startswith(b"\xef\xbb\xbf") else line


def _lines(source: bytes | str | os.PathLike | BinaryIO, what: str) -> Iterator[tuple[int, bytes | None]]:
    """The lines of the content, a file or an open binary file (:func:`_stream`)."""
    if isinstance(source, os.PathLike):
        try:
            fh = open(source, "rb")
        except OSError as exc:
            raise InputError(f"{what}: cannot read {source}: {exc.strerror or exc}") from None
        with fh:
            yield from _stream(fh)
    elif isinstance(source, (bytes, bytearray)):
        yield from _stream(io.BytesIO(source))  # shares the bytes: no copy
    elif isinstance(source, str):
        yield from _stream(io.BytesIO(source.encode("utf-8", "surrogatepass")))
    elif hasattr(source, "readline"):
        yield from _stream(source)
    else:
        raise InputError(f"{what}: a {type(source).__name__}, not bytes, str, a path or a binary file")


def _record(line: bytes, n: int, what: str) -> Any:
    """A line's JSON value; ValueError (one line) when it is not JSON."""
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{what}: not UTF-8 text (line {n}, byte {exc.start})") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(exc.msg) from None
    except RecursionError:
        raise ValueError("nested too deeply") from None
    # any other ValueError (an integer of more than 4300 digits) says itself what is wrong


def read_jsonl(source: bytes | str | os.PathLike | BinaryIO,
               what: str = "executed file", filters: Sequence[str] = FILTERS) -> tuple[ExecutedExposure, ...]:
    """Exposures of a JSON-lines file: one record per line, exactly the record's keys.

    ``{"field_id": 600, "filter": "g", "start": "2026-05-01T04:00:00.000Z",
    "exposure_s": 300.0, "processed_fraction": 1.0, "status": "processed"}``;
    blank lines are ignored, lines are numbered from 1.  Read line by line:
    memory grows with the records kept, not with the file.

    Parameters
    ----------
    source : bytes, str, path or binary file
        The content, the file, or the file opened (``rb``; streamed, not closed).
    what : str
        Name of the source in messages.
    filters : sequence of str
        The telescope's filters (default ZTF's g, r, i); a line of another filter is skipped.

    Returns
    -------
    tuple of ExecutedExposure
        In start order.

    Raises
    ------
    InputError
        Not UTF-8 text, or not one line of it is JSON (a JSON document
        spread over lines, a binary file).
    """
    what = _named(source, what)
    out = []
    lines = json_lines = 0
    skipped = _Skipped(what)
    for n, line in _lines(source, what):
        if line is not None and not line.strip():
            continue
        lines += 1
        if line is None:
            skipped(f"line {n}", f"longer than {MAX_LINE_BYTES} bytes")
            continue
        try:
            record = _record(line, n, what)
        except InputError:
            raise
        except ValueError as exc:
            skipped(f"line {n}", f"not JSON ({exc})")
            continue
        json_lines += 1
        try:
            out.append(from_record(record, filters))
        except InputError as exc:
            skipped(f"line {n}", exc)
    if lines and not json_lines:
        raise InputError(f"{what}: not JSON lines (none of its {lines} lines is JSON)")
    skipped.done()
    return unique_exposures(out)


def write_jsonl(exposures: Iterable[ExecutedExposure], path: str | os.PathLike) -> Path:
    """Write records as JSON lines (:func:`read_jsonl` reads them back), in the order given.

    The file is written whole to a temporary neighbour and renamed, so a
    reader never sees half of it.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    path = Path(path)
    text = "".join(json.dumps(to_record(e), allow_nan=False) + "\n" for e in exposures)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)
    return path
