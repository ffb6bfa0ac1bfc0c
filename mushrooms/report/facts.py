"""The facts of a plan document a person reads, computed once for the text and the HTML summary.

Everything here is read from the plan document alone (``docs/design/plan-format.md``),
so the same summary is written beside a published plan in the outbox, beside
``mushrooms plan -o P.json`` and shown by ``mushrooms status``.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

__all__ = ["PlanFacts", "ExposureRow", "plan_facts", "palomar_time", "duration_words", "percent", "depth_words",
           "shown"]

#: The P48's time zone (Palomar Observatory, California).
PALOMAR_TZ = "America/Los_Angeles"


def shown(text: Any, limit: int = 200) -> str:
    """Text of a document as a summary shows it: one line, no control, bidi or separator character raw
    (:func:`~mushrooms.handlers.text.storable`), at most ``limit`` characters."""
    from ..handlers.text import storable

    return storable(text, limit)


@dataclass(frozen=True)
class ExposureRow:
    """One exposure as the table shows it.

    Attributes
    ----------
    field_id : int
    filter : str
    start : datetime.datetime
        UTC.
    exposure_s : float
    airmass : float or None
    share : float or None
        The field's own share of the probability (0-1; overlaps divided).
    coverage_after : float or None
        Total coverage after this exposure (0-1; a re-plan: the executed part included).
    limiting_mag : float or None
        5-sigma depth (AB) the exposure is expected to reach (D2).
    ra, dec : float or None
        The field's centre (deg, ICRS).
    """

    field_id: int
    filter: str
    start: dt.datetime
    exposure_s: float
    airmass: float | None
    share: float | None
    coverage_after: float | None
    limiting_mag: float | None = None
    ra: float | None = None
    dec: float | None = None


@dataclass(frozen=True)
class PlanFacts:
    """What a summary says about one revision (times UTC, probabilities 0-1)."""

    kind: str
    title: str
    event: Mapping[str, Any]
    revision: int | None
    final: bool | None
    queues: tuple[str, ...]
    queue_note: str
    first: dt.datetime | None
    last_end: dt.datetime | None
    n_fields: int
    n_exposures: int
    filters: tuple[str, ...]
    open_shutter_s: float
    overhead_s: float
    waiting_s: float
    coverage: float
    coverage_executed: float | None
    upper_bound: float | None
    expected_detections: float | None
    solver: str
    status: str
    rows: tuple[ExposureRow, ...]
    reasons: tuple[str, ...]
    #: the first exposure's start after the merger, and after the alert was created (s; None: unknown)
    after_merger_s: float | None = None
    after_alert_s: float | None = None
    nside: int | None = None
    #: the plan's telescope and site (:func:`.site.plan_site`; ZTF at Palomar when the document names none)
    site: Any = None
    #: the plan's ``config.filters`` as written (its covering visits: which detectors make a field covered)
    sequence: tuple[str, ...] = ()


def _filters(doc: Mapping[str, Any], rows: Sequence[ExposureRow]) -> tuple[str, ...]:
    """The filters in order of first use; a sequence longer than a pair as one name (``("g-r-g",)``)."""
    sequence = (doc.get("config") or {}).get("filters") or ()
    if isinstance(sequence, (list, tuple)) and len(sequence) > 2 and rows:
        return ("-".join(str(f) for f in sequence),)
    return tuple(dict.fromkeys(r.filter for r in rows))


def _sequence(doc: Mapping[str, Any]) -> tuple[str, ...]:
    """``config.filters`` as a tuple of names (empty when absent or not a list)."""
    sequence = (doc.get("config") or {}).get("filters") or ()
    return tuple(str(f)[:40] for f in sequence) if isinstance(sequence, (list, tuple)) else ()


def _site(doc: Mapping[str, Any]) -> Any:
    from .site import plan_site

    return plan_site(doc)


def _utc(text: str | None) -> dt.datetime | None:
    if not text:
        return None
    return dt.datetime.fromisoformat(text.replace("Z", "+00:00")).astimezone(dt.timezone.utc)


def _since(first: dt.datetime | None, text: Any) -> float | None:
    """Seconds from the instant ``text`` (ISO 8601) to ``first``; None when either is unknown or unreadable."""
    try:
        then = _utc(text) if isinstance(text, str) else None
    except ValueError:
        return None
    return None if first is None or then is None else (first - then).total_seconds()


def _number(value: Any) -> float | None:
    return None if value is None else float(value)


def percent(p: float | None, digits: int = 1) -> str:
    """A probability as a percentage (``"66.5 %"``); ``"unknown"`` for None."""
    return "unknown" if p is None else f"{100.0 * p:.{digits}f} %"


def duration_words(seconds: float) -> str:
    """``4 h 45 min``, ``12 min``, ``40 s`` (rounded to the minute above a minute)."""
    s = abs(float(seconds))
    if s < 60:
        return f"{s:.0f} s"
    minutes = int(round(s / 60.0))
    h, m = divmod(minutes, 60)
    if h >= 48:
        return f"{h // 24} d {h % 24} h"
    return f"{h} h {m} min" if h else f"{m} min"


def palomar_time(t: dt.datetime) -> str:
    """Palomar local clock time with its zone (``20:57 PDT``)."""
    try:
        from zoneinfo import ZoneInfo

        local = t.astimezone(ZoneInfo(PALOMAR_TZ))
        return local.strftime("%H:%M %Z")
    except Exception:  # no time-zone database: Pacific standard time
        return (t - dt.timedelta(hours=8)).strftime("%H:%M") + " UTC-8"


def depth_words(rows: Sequence[ExposureRow]) -> str | None:
    """``g 21.4, r 21.6 mag (median; 20.9-22.0)``: the exposures' 5-sigma depths per filter; None without any."""
    by_filter: dict[str, list[float]] = {}
    for r in rows:
        if r.limiting_mag is not None:
            by_filter.setdefault(r.filter, []).append(r.limiting_mag)
    if not by_filter:
        return None
    every = sorted(m for ms in by_filter.values() for m in ms)
    medians = ", ".join(f"{f} {sorted(ms)[len(ms) // 2]:.1f}" for f, ms in by_filter.items())
    return f"{medians} mag (median 5σ, AB, difference image; {every[0]:.1f}-{every[-1]:.1f})"


def _queues(doc: Mapping[str, Any], queues: Sequence[str] | None) -> tuple[str, ...]:
    """The ZTF queue names of the revision: given, else the document's ``queues``, else none (a name is never
    guessed: the names come from the one rule, ``exports.queue_name_base``, through the caller)."""
    if queues:
        return tuple(shown(q) for q in queues)
    listed = doc.get("queues")
    if isinstance(listed, list) and listed:
        return tuple(shown(q.get("queue_name", q) if isinstance(q, Mapping) else q) for q in listed)
    return ()


def _timing(obs: Sequence[Mapping[str, Any]]) -> tuple[float, float, float]:
    """Open-shutter time, overheads within blocks (slews, readouts, filter changes) and waits between blocks (s)."""
    shutter = sum(float(o["exposure_s"]) for o in obs)
    overhead = waiting = 0.0
    for a, b in zip(obs[:-1], obs[1:]):
        gap = (_utc(b["start"]) - _utc(a["end"])).total_seconds()
        if a.get("block") == b.get("block"):
            overhead += max(gap, 0.0)
        else:
            waiting += max(gap, 0.0)
    return shutter, overhead, waiting


def plan_facts(doc: Mapping[str, Any], queues: Sequence[str] | None = None, queue_note: str = "") -> PlanFacts:
    """The facts of a plan (or not_observable) document.

    Parameters
    ----------
    doc : mapping
        A plan document (``type`` ``plan`` or ``not_observable``).
    queues : sequence of str, optional
        The ZTF queue names the revision went (or would go) to, in
        submission order (default: the document's ``queues``, else none shown).
    queue_note : str
        What became of them (``submitted to kowalski``, ``not submitted: ...``).
    """
    event = doc.get("event") or {}
    metrics = doc.get("metrics") or {}
    obs = sorted(doc.get("observations") or [], key=lambda o: o["start"])
    done = metrics.get("coverage_executed")
    offset = float(done or 0.0)
    rows = tuple(ExposureRow(int(o["field_id"]), shown(o["filter"], 8), _utc(o["start"]), float(o["exposure_s"]),
                             o.get("airmass"), o.get("probability_share"),
                             None if o.get("coverage_after") is None else offset + float(o["coverage_after"]),
                             _number(o.get("limiting_mag")), _number(o.get("ra")), _number(o.get("dec")))
                 for o in obs)
    shutter, overhead, waiting = _timing(obs)
    title = shown(event.get("superevent_id") or event.get("skymap_name") or "sky map")
    reasons = tuple(doc.get("reasons") or ()) if doc.get("type") == "not_observable" else ()
    reasons = tuple(shown(r.get("sentence", str(r)) if isinstance(r, Mapping) else r, 1000) for r in reasons)
    return PlanFacts(
        kind=str(doc.get("type", "plan")), title=str(title), event=event, revision=doc.get("revision"),
        final=doc.get("final"), queues=_queues(doc, queues) if obs else (), queue_note=queue_note,
        first=rows[0].start if rows else None, last_end=_utc(obs[-1]["end"]) if obs else None,
        n_fields=len({r.field_id for r in rows}), n_exposures=len(rows),
        filters=_filters(doc, rows), open_shutter_s=shutter, overhead_s=overhead,
        waiting_s=waiting, coverage=float(metrics.get("coverage") or 0.0), coverage_executed=done,
        upper_bound=metrics.get("upper_bound"), expected_detections=metrics.get("expected_detections"),
        solver=str(metrics.get("solver", "")), status=str(metrics.get("status", "")), rows=rows, reasons=reasons,
        after_merger_s=_since(rows[0].start if rows else None, event.get("event_time")),
        after_alert_s=_since(rows[0].start if rows else None, event.get("time_created")),
        nside=(doc.get("config") or {}).get("nside"), site=_site(doc), sequence=_sequence(doc))
