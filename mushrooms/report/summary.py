"""The text summary of a plan revision: what an observer on call reads at 3 a.m.

:func:`summary_text` is the short page (event, queue, timing, coverage and
expected detections in words, the certified bound in one sentence, one row
per exposure); :func:`answer_line` the one line ``mushrooms plan`` and the
demo end with.  Both read the plan document only (:mod:`.facts`).
"""

from __future__ import annotations

import datetime as dt
from typing import Any, Mapping, Sequence

from .facts import PlanFacts, depth_words, duration_words, percent, plan_facts, shown
from .site import at_site

__all__ = ["summary_text", "answer_line", "event_lines", "bound_sentence", "status_words", "starts_in",
           "queue_words", "delay_words", "covered"]


def _far_words(far_hz: float | None) -> str | None:
    """A false-alarm rate as a person says it (``1 per 3.2e+05 years``)."""
    if far_hz is None:
        return None
    if far_hz <= 0:
        return "0 (none expected)"
    per_year = far_hz * 365.25 * 86400.0
    return f"{far_hz:.2g} Hz, one false alarm per {1.0 / per_year:.2g} years"


def event_lines(event: Mapping[str, Any], covered_deg2: float | None = None) -> list[str]:
    """The event in a few lines: superevent and alert type, classification, FAR, distance and areas
    (``covered_deg2``: the sky area the plan's fields cover, deg²)."""
    lines = [f"Event      {shown(event.get('superevent_id') or event.get('skymap_name') or 'a sky map')}"
             + (f" ({shown(event['alert_type'], 40)})" if event.get("alert_type") else "")]
    cls = event.get("classification") or {}
    if cls:
        ranked = sorted(cls.items(), key=lambda kv: -kv[1])
        p_astro = 1.0 - float(cls.get("Terrestrial", 0.0))
        lines.append("Source     " + ", ".join(f"{shown(k, 40)} {percent(v, 0)}" for k, v in ranked if v >= 0.005)
                     + f"; p_astro {p_astro:.2f}")
    far = _far_words(event.get("far_hz"))
    if far:
        lines.append(f"FAR        {far}")
    if event.get("distance_mpc") is not None:
        std = event.get("distance_std_mpc")
        lines.append(f"Distance   {event['distance_mpc']:.0f}" + (f" ± {std:.0f}" if std is not None else "") + " Mpc")
    areas = [f"{event.get('area_50_deg2', 0):.0f} deg² (50 %), {event['area_90_deg2']:.0f} deg² (90 %)"
             ] if event.get("area_90_deg2") is not None else []
    if covered_deg2 is not None:
        areas.append(f"the fields cover {covered_deg2:,.0f} deg²")
    if areas:
        lines.append("Area       " + "; ".join(areas))
    if event.get("event_time"):
        lines.append(f"Merger     {shown(event['event_time'], 40)[:19].replace('T', ' ')} UTC")
    return lines


def delay_words(facts: PlanFacts) -> str | None:
    """``first exposure 6 h 0 min after the merger, 5 h 53 min after the alert``; None when neither is known."""
    parts = [f"{duration_words(s)} {'after' if s >= 0 else 'before'} the {what}"
             for s, what in ((facts.after_merger_s, "merger"), (facts.after_alert_s, "alert")) if s is not None]
    return "first exposure " + ", ".join(parts) if parts else None


def covered(facts: PlanFacts) -> float | None:
    """The sky area (deg²) the plan's fields cover on its own telescope's grid and detectors
    (:func:`.sky.covered_area_deg2`), None without fields or for a telescope not shipped."""
    from .sky import covered_area_deg2

    if not facts.rows:
        return None
    return covered_area_deg2([r.field_id for r in facts.rows], facts.nside or 0, facts.site.entry, facts.sequence)


def starts_in(first: dt.datetime, now: dt.datetime) -> str:
    """``starts in 4 h 45 min``, ``started 12 min ago``."""
    seconds = (first - now).total_seconds()
    return f"starts in {duration_words(seconds)}" if seconds >= 0 else f"started {duration_words(seconds)} ago"


def bound_sentence(facts: PlanFacts) -> str | None:
    """The certified bound as one plain sentence, and what ``optimal`` means beside it; None without a bound."""
    if facts.upper_bound is None:
        return None
    total = facts.coverage + float(facts.coverage_executed or 0.0)
    bound = float(facts.upper_bound) + float(facts.coverage_executed or 0.0)
    share = f" This plan reaches {total / bound:.0%} of that." if bound > 0 else ""
    sentence = f"No plan that obeys these rules can cover more than {percent(bound)}.{share}"
    if facts.status == "optimal":
        sentence += (" (\"optimal\" means best within the solver's model of the night, fixed blocks or slots; "
                     "the bound holds for every plan the rules allow.)")
    return sentence


def status_words(facts: PlanFacts) -> str:
    """How the plan was found, in words."""
    if facts.solver == "greedy" or facts.status == "greedy":
        return "the quick greedy plan (an optimised one may follow)" if facts.final is False else "the greedy plan"
    words = {"optimal": "solved to optimality within its model", "time_limit": "best found in the time allowed",
             "work_limit": "best found in the work allowed"}
    return f"{facts.solver}, {words.get(facts.status, facts.status)}"


def queue_words(facts: PlanFacts, every: bool = False) -> str | None:
    """The revision's ZTF queues in words: how many, what became of them, their names (the first and the last
    unless ``every``); None without any."""
    names = facts.queues
    if not names:
        return None
    if len(names) == 1:
        return names[0] + (f" ({facts.queue_note})" if facts.queue_note else "")
    shown = ", ".join(names) if every else f"{names[0]} … {names[-1]}"
    note = f"; {facts.queue_note}" if facts.queue_note else ""
    return f"{len(names)} queues, one per filter pass{note}: {shown}"


def _coverage_words(facts: PlanFacts) -> list[str]:
    lines = []
    if facts.coverage_executed is not None:
        done = float(facts.coverage_executed)
        lines.append(f"Done       {percent(done)} of the probability was already covered by executed exposures")
        lines.append(f"Added      this plan adds {percent(facts.coverage)}")
        lines.append(f"Total      {percent(done + facts.coverage)} of the probability after this plan")
    else:
        lines.append(f"Coverage   the fields hold {percent(facts.coverage)} of the probability")
    depth = depth_words(facts.rows)
    if depth:
        lines.append(f"Depth      {depth}")
    if facts.expected_detections is not None:
        lines.append(f"Detection  a kilonova like the configured light curve would be detected with probability "
                     f"{percent(facts.expected_detections)}")
    bound = bound_sentence(facts)
    if bound:
        lines.append(f"Bound      {bound}")
    return lines


def _timing_lines(facts: PlanFacts, now: dt.datetime) -> list[str]:
    if facts.first is None or facts.last_end is None:
        return []
    delay = delay_words(facts)
    lines = [f"First      {facts.first:%Y-%m-%d %H:%M} UTC{at_site(facts.first, facts.site)}, "
             f"{starts_in(facts.first, now)}"] + ([f"Delay      {delay}"] if delay else []) + [
             f"Last ends  {facts.last_end:%Y-%m-%d %H:%M} UTC{at_site(facts.last_end, facts.site)}",
             f"Shutter    {duration_words(facts.open_shutter_s)} open, {duration_words(facts.overhead_s)} of "
             "slews, readouts, filter changes and cadence waits"
             + (f", {duration_words(facts.waiting_s)} waiting between blocks" if facts.waiting_s >= 60 else "")]
    return lines


def _rows(facts: PlanFacts) -> list[str]:
    """One line per exposure: field, filter, start, place (RA, Dec, deg), exposure time, distance from the
    Moon (deg), airmass, depth, own probability, coverage after."""
    from .sky import moon_distances

    head = (f"{'field':>6} {'filter':>6}  {'start (UTC)':<16} {'RA':>6} {'Dec':>6} {'exp':>5} {'Moon':>4}"
            f" {'airmass':>7} {'depth':>5} {'own prob':>8} {'coverage':>8}")
    out = [head]
    for r, moon in zip(facts.rows, moon_distances(facts.rows, facts.site)):
        airmass = "" if r.airmass is None else f"{r.airmass:.2f}"
        depth = "" if r.limiting_mag is None else f"{r.limiting_mag:.1f}"
        share = "" if r.share is None else percent(r.share, 2)
        after = "" if r.coverage_after is None else percent(r.coverage_after, 1)
        ra, dec = ("", "") if r.ra is None or r.dec is None else (f"{r.ra:.2f}", f"{r.dec:+.2f}")
        away = "" if moon is None else f"{moon:.0f}°"
        out.append(f"{r.field_id:>6} {r.filter:>6}  {r.start:%m-%d %H:%M:%S}   {ra:>6} {dec:>6} "
                   f"{r.exposure_s:>4.0f}s {away:>4} {airmass:>7} {depth:>5} {share:>8} {after:>8}")
    return out


def summary_text(doc: Mapping[str, Any], now: dt.datetime | None = None, queues: Sequence[str] | None = None,
                 rows: bool = True, queue_note: str = "") -> str:
    """The text summary of a plan or not_observable document.

    Parameters
    ----------
    doc : mapping
        The document (``docs/design/plan-format.md``).
    now : datetime, optional
        The clock of "starts in" (default: now, UTC).
    queues : sequence of str, optional
        ZTF queue names of the revision (:func:`.facts.plan_facts`).
    rows : bool
        Include the one-row-per-exposure table.
    queue_note : str
        What became of the queues (``submitted to kowalski``).
    """
    now = now or dt.datetime.now(dt.timezone.utc)
    facts = plan_facts(doc, queues, queue_note)
    revision = "" if facts.revision is None else f" revision {facts.revision}" + (
        " (final)" if facts.final else " (may be superseded)" if facts.final is False else "")
    area = covered(facts) if facts.kind != "not_observable" else None
    lines = [f"Revision   {shown(doc.get('plan_id', ''))}{revision}"] + event_lines(facts.event, area)
    if facts.kind == "not_observable":
        lines.append(f"Answer     NOT OBSERVABLE by {facts.site.telescope}: "
                     + (facts.reasons[0] if facts.reasons else "no field in reach"))
        lines += [f"           {r}" for r in facts.reasons[1:]]
        return "\n".join(lines) + "\n"
    lines.append(f"Planned    {answer_line(doc)}")
    queue = queue_words(facts)
    if queue:
        lines.append(f"Queue      {queue}")
    lines += _timing_lines(facts, now) + _coverage_words(facts)
    lines.append(f"Found by   {status_words(facts)}")
    if rows and facts.rows:
        lines += [""] + _rows(facts)
    return "\n".join(lines) + "\n"


def answer_line(doc: Mapping[str, Any]) -> str:
    """What was planned, in one line (``24 fields in g and r, 48 exposures from 03:57 to 06:31 UTC, ...``)."""
    facts = plan_facts(doc)
    if facts.kind == "not_observable":
        return (f"{facts.title} is not observable by {facts.site.telescope}: "
                + (facts.reasons[0] if facts.reasons else "nothing in reach"))
    if not facts.rows:
        return f"{facts.title}: nothing to observe"
    filters = " and ".join(facts.filters)
    total = facts.coverage + float(facts.coverage_executed or 0.0)
    covered = (f"adding {percent(facts.coverage)} to the {percent(facts.coverage_executed)} done "
               f"(total {percent(total)})" if facts.coverage_executed is not None
               else f"covering {percent(facts.coverage)} of the probability")
    bound = "" if facts.upper_bound is None else \
        f" (no plan can cover more than {percent(float(facts.upper_bound) + float(facts.coverage_executed or 0))})"
    detect = "" if facts.expected_detections is None else \
        f"; kilonova detection chance {percent(facts.expected_detections)}"
    days = (facts.last_end.date() - facts.first.date()).days
    later = "" if days <= 0 else " the next day" if days == 1 else f" {days} days later"
    return (f"{facts.n_fields} fields in {filters}, {facts.n_exposures} exposures from {facts.first:%H:%M} to "
            f"{facts.last_end:%H:%M} UTC{later}, {covered}{bound}{detect}")
