"""The HTML summary of a plan revision: one self-contained page (the picture embedded as a base64 PNG).

The same facts as the text summary (:mod:`.summary`): a statistics table
(event, queue, first and last exposure in UTC and the site's time, open-shutter
time and overheads, coverage, expected detections, the certified bound), the
picture, and one row per exposure.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
from typing import Any, Mapping, Sequence

from .facts import PlanFacts, depth_words, duration_words, percent, plan_facts, shown
from .site import at_site
from .summary import answer_line, bound_sentence, covered, delay_words, event_lines, queue_words, starts_in, status_words

__all__ = ["summary_html"]

_STYLE = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#111;max-width:70em}
h1{font-size:1.4em;margin-bottom:.2em} p.answer{font-size:1.1em;margin-top:.2em}
table{border-collapse:collapse;margin:.6em 0} td,th{padding:.15em .7em;border-bottom:1px solid #ddd;text-align:left}
table.rows td{text-align:right;font-variant-numeric:tabular-nums} th{background:#f3f3f3}
.warn{color:#a00000;font-weight:bold} img{max-width:100%;border:1px solid #ccc}
"""


def _cell(text: Any) -> str:
    return html.escape(str(text))


def _stats(facts: PlanFacts, now: dt.datetime) -> list[tuple[str, str]]:
    """(label, value) rows of the statistics table."""
    rows = [(line[:10].strip(), line[10:].strip()) for line in event_lines(facts.event, covered(facts))]
    queue = queue_words(facts, every=True)
    if queue:
        rows.append(("Queue", queue))
    if facts.first is not None and facts.last_end is not None:
        rows += [("First exposure", f"{facts.first:%Y-%m-%d %H:%M} UTC{at_site(facts.first, facts.site)}, "
                                    f"{starts_in(facts.first, now)}")]
        delay = delay_words(facts)
        rows += [("Delay", delay)] if delay else []
        rows += [("Last exposure ends", f"{facts.last_end:%Y-%m-%d %H:%M} UTC"
                                        f"{at_site(facts.last_end, facts.site, named=False)}"),
                 ("Exposures", f"{facts.n_exposures} exposures of {facts.n_fields} fields in "
                               f"{' and '.join(facts.filters)}"),
                 ("Open shutter", duration_words(facts.open_shutter_s)),
                 ("Overheads", f"{duration_words(facts.overhead_s)} (slews, readouts, filter changes, cadence "
                               f"waits); {duration_words(facts.waiting_s)} between blocks")]
    if facts.coverage_executed is not None:
        rows += [("Done before", percent(facts.coverage_executed)), ("Added", percent(facts.coverage)),
                 ("Total coverage", percent(facts.coverage + float(facts.coverage_executed)))]
    else:
        rows.append(("Coverage", percent(facts.coverage)))
    depth = depth_words(facts.rows)
    if depth:
        rows.append(("Depth", depth))
    if facts.expected_detections is not None:
        rows.append(("Kilonova detection", f"probability {percent(facts.expected_detections)}"))
    bound = bound_sentence(facts)
    if bound:
        rows.append(("Bound", bound))
    rows.append(("Found by", status_words(facts)))
    return rows


def _where(facts: PlanFacts) -> str:
    """The site the Moon's distances are seen from (``Palomar``; geocentric when the site is unknown)."""
    return facts.site.name or ("the site" if facts.site.known else "site unknown: not shown")


def _exposure_table(facts: PlanFacts) -> str:
    from .sky import moon_distances

    head = ("<tr><th>#</th><th>field</th><th>filter</th><th>start (UTC)</th><th>RA (deg)</th><th>Dec (deg)</th>"
            f"<th>exposure (s)</th><th title=\"distance from the Moon at the start ({_cell(_where(facts))})\">"
            "Moon (deg)</th>"
            "<th>airmass</th>"
            "<th title=\"5-sigma limiting magnitude (AB) of the difference image\">depth (mag)</th>"
            "<th>own probability</th><th>coverage after</th></tr>")
    body = []
    for k, (r, moon) in enumerate(zip(facts.rows, moon_distances(facts.rows, facts.site)), 1):
        body.append(
            f"<tr><td>{k}</td><td>{r.field_id}</td><td>{_cell(r.filter)}</td><td>{r.start:%Y-%m-%d %H:%M:%S}</td>"
            f"<td>{'' if r.ra is None else f'{r.ra:.2f}'}</td><td>{'' if r.dec is None else f'{r.dec:+.2f}'}</td>"
            f"<td>{r.exposure_s:.0f}</td><td>{'' if moon is None else f'{moon:.0f}'}</td>"
            f"<td>{'' if r.airmass is None else f'{r.airmass:.2f}'}</td>"
            f"<td>{'' if r.limiting_mag is None else f'{r.limiting_mag:.1f}'}</td>"
            f"<td>{'' if r.share is None else percent(r.share, 2)}</td>"
            f"<td>{'' if r.coverage_after is None else percent(r.coverage_after)}</td></tr>")
    return f"<table class=\"rows\">{head}{''.join(body)}</table>"


def summary_html(doc: Mapping[str, Any], picture_png: bytes | None = None, now: dt.datetime | None = None,
                 queues: Sequence[str] | None = None, queue_note: str = "") -> str:
    """A self-contained HTML page of a plan or not_observable document.

    Parameters
    ----------
    doc : mapping
        The document.
    picture_png : bytes, optional
        The plan's picture (PNG), embedded as a ``data:`` URI.
    now : datetime, optional
        The clock of "starts in" (default: now, UTC).
    queues : sequence of str, optional
        ZTF queue names (:func:`.facts.plan_facts`).
    queue_note : str
        What became of them.
    """
    now = now or dt.datetime.now(dt.timezone.utc)
    facts = plan_facts(doc, queues, queue_note)
    revision = "" if facts.revision is None else f", revision {facts.revision}" + (" (final)" if facts.final else "")
    parts = [f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{_cell(facts.title)} plan"
             f"</title><style>{_STYLE}</style></head><body>",
             f"<h1>{_cell(facts.title)}: {_cell(facts.site.telescope)} plan{_cell(revision)}</h1>"]
    if facts.kind == "not_observable":
        parts.append(f"<p class=\"warn\">{_cell(answer_line(doc))}</p><ul>"
                     + "".join(f"<li>{_cell(r)}</li>" for r in facts.reasons) + "</ul>")
    else:
        parts.append(f"<p class=\"answer\">{_cell(answer_line(doc))}</p>")
    parts.append("<table>" + "".join(f"<tr><th>{_cell(k)}</th><td>{_cell(v)}</td></tr>" for k, v in _stats(facts, now))
                 + "</table>")
    if picture_png:
        data = base64.b64encode(picture_png).decode("ascii")
        parts.append(f"<p><img alt=\"the plan on the sky and its airmass over the night\" "
                     f"src=\"data:image/png;base64,{data}\"></p>")
    if facts.rows:
        parts.append("<h2>Exposures</h2>" + _exposure_table(facts))
    parts.append(f"<p><small>plan {_cell(shown(doc.get('plan_id', '')))}, made {_cell(shown(doc.get('created', '')))}"
                 "</small></p></body></html>\n")
    return "".join(parts)
