"""The release's tables (issue 55) from a population ``results.csv``: every number with its spread, paired per event.

Input: :data:`~.population_rows.POPULATION_COLUMNS` rows, one per (event,
row), the rows named :data:`RELEASE_ROWS`.  Only the events with a row of
every row name present (or asked for: ``expected``) are tabulated (a
partial run's comparable set); the others are listed in the header with the
rows they lack.  Rows from more than one commit (or from a dirty tree, or
without a commit) put a warning at the top.  Output (Markdown):

* the headline table: per row and metric (:data:`METRICS`: planned
  coverage by the pair rule, executed through the queue set, executed as
  submitted today, detection by the two-detection rule and by one
  detection, open-shutter hours planned and executed via the queue set), the mean with its bootstrap 95 %
  interval and the median with its own;
* per-event paired differences against the service (row minus service over
  the events both have): mean and median with bootstrap 95 % intervals,
  events better / worse / tied;
* with our rows' executed curves, the same at matched telescope time: each
  of our rows at gwemopt's open-shutter time on the event
  (:mod:`.matched_tables`);
* events where each row executes nothing (through the queue set and as
  submitted today) or pairs nothing as planned, and the plans the checker
  passed;
* the same medians by event class, distance quartile and 90 % area quartile.

The bootstrap (:mod:`.release_stats`) resamples events with replacement (``draws`` times, one
seeded generator per statistic, so a table is the same on every run) and
takes the 2.5th and 97.5th percentiles of the statistic.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from ..bench.rows import num
from .release_stats import TIE, bootstrap_interval, cell, metric_values, summary

__all__ = ["RELEASE_ROWS", "REFERENCE", "METRICS", "TIE", "bootstrap_interval", "summary", "release_events",
           "incomplete_events", "commits_of", "metric_values", "paired_differences", "zero_counts", "metric_table",
           "paired_table", "zero_table", "breakdown_table", "release_tables"]

Record = Mapping[str, Any]

#: The rows of the release, in table order (others present follow).
RELEASE_ROWS = ("service", "service-grg", "greedy", "gwemopt-o4", "gwemopt-skyportal", "gwemopt-repaired")
#: Paired differences are against this row.
REFERENCE = "service"
#: (column, label, scale) of the metrics tabulated; values are multiplied by ``scale`` (seconds to hours).
METRICS = (
    ("coverage_pairs", "planned (pair rule)", 1.0),
    ("coverage_executed", "executed via queue set", 1.0),
    ("coverage_executed_single_queue", "executed as submitted today", 1.0),
    ("efficiency_two_detections", "detection (two detections ≥ 15 min)", 1.0),
    ("efficiency_optimistic", "detection (one detection, optimistic)", 1.0),
    ("open_shutter_s", "open shutter planned (h)", 1.0 / 3600.0),
    ("open_shutter_executed_s", "open shutter executed via queue set (h)", 1.0 / 3600.0),
)
#: A coverage at or below this is "nothing executed".
ZERO = 1e-9


def _by_event(rows: Sequence[Record]) -> dict[str, dict[str, Record]]:
    out: dict[str, dict[str, Record]] = {}
    for r in rows:
        out.setdefault(str(r["event"]), {})[str(r["solver"])] = r
    return out


def _solvers(rows: Sequence[Record]) -> list[str]:
    present = list(dict.fromkeys(str(r["solver"]) for r in rows))
    return [s for s in RELEASE_ROWS if s in present] + [s for s in present if s not in RELEASE_ROWS]


def _expected(rows: Sequence[Record], expected: Sequence[str] | None) -> set[str]:
    """The row names an event needs to be compared: ``expected`` and every row name present (None: those present)."""
    return set(_solvers(rows)) | set(expected or ())


def _done(sol: Mapping[str, Record]) -> set[str]:
    """The row names of one event with a scored plan (a coverage; a failed task's row has none)."""
    return {s for s, r in sol.items() if num(r.get("coverage")) is not None}


def release_events(rows: Sequence[Record], expected: Sequence[str] | None = None) -> list[Record]:
    """The rows of the events that have a scored row of every row name present (and of every name of
    ``expected``)."""
    solvers = _expected(rows, expected)
    return [r for sol in _by_event(rows).values() if _done(sol) >= solvers for r in sol.values()]


def incomplete_events(rows: Sequence[Record], expected: Sequence[str] | None = None) -> dict[str, list[str]]:
    """Event -> the row names it lacks a scored row of ("failed" after one whose task failed), for the events
    :func:`release_events` leaves out (a partial run's events whose rows are not all done), in event order."""
    solvers = _expected(rows, expected)
    order = [s for s in RELEASE_ROWS if s in solvers] + sorted(solvers - set(RELEASE_ROWS))
    return {e: [s + (" (failed)" if s in sol else "") for s in order if s not in _done(sol)]
            for e, sol in _by_event(rows).items() if not _done(sol) >= solvers}


def paired_differences(rows: Sequence[Record], solver: str, column: str, reference: str = REFERENCE,
                       scale: float = 1.0) -> dict[str, float]:
    """Event -> ``solver`` minus ``reference`` in ``column`` over the events both have a number for."""
    a = metric_values(rows, solver, column, scale)
    b = metric_values(rows, reference, column, scale)
    return {e: a[e] - b[e] for e in a if e in b}


def zero_counts(rows: Sequence[Record], solver: str) -> dict[str, int]:
    """Of ``solver``'s events: ``events``, and how many pair nothing as planned (``planned``), execute nothing
    through the queue set (``queue_set``) or as submitted today (``single_queue``); ``valid`` plans."""
    mine = [r for r in rows if str(r["solver"]) == solver]

    def zeros(column: str) -> int:
        return sum(1 for r in mine if (v := num(r.get(column))) is not None and v <= ZERO)

    return dict(events=len(mine), planned=zeros("coverage_pairs"), queue_set=zeros("coverage_executed"),
                single_queue=zeros("coverage_executed_single_queue"),
                valid=sum(1 for r in mine if r.get("valid") is True))


def _fmt(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def metric_table(rows: Sequence[Record], draws: int = 2000, seed: int = 0) -> list[str]:
    """Markdown: per row, each metric's mean [95 %] / median [95 %] over the events (n per row)."""
    solvers = _solvers(rows)
    lines = ["| row | events | " + " | ".join(label for _, label, _ in METRICS) + " |",
             "|" + "---|" * (2 + len(METRICS))]
    for s in solvers:
        n = len({str(r["event"]) for r in rows if str(r["solver"]) == s})
        cells = [cell(summary(list(metric_values(rows, s, c, k).values()), draws, seed), 2 if k != 1.0 else 3)
                 for c, _, k in METRICS]
        lines.append(f"| {s} | {n} | " + " | ".join(cells) + " |")
    return lines


def paired_table(rows: Sequence[Record], reference: str = REFERENCE, draws: int = 2000, seed: int = 0) -> list[str]:
    """Markdown: per row and metric, the per-event difference from ``reference``: mean [95 %] / median [95 %]
    (events better/worse/tied beyond :data:`TIE`)."""
    solvers = [s for s in _solvers(rows) if s != reference]
    lines = ["| row − " + reference + " | " + " | ".join(label for _, label, _ in METRICS) + " |",
             "|" + "---|" * (1 + len(METRICS))]
    for s in solvers:
        cells = []
        for c, _, k in METRICS:
            d = list(paired_differences(rows, s, c, reference, k).values())
            summ = summary(d, draws, seed)
            tally = (f" ({sum(x > TIE for x in d)}/{sum(x < -TIE for x in d)}/{sum(abs(x) <= TIE for x in d)}"
                     f" of {len(d)})") if d else ""
            cells.append(cell(summ, 2 if k != 1.0 else 3, sign=True) + tally)
        lines.append(f"| {s} | " + " | ".join(cells) + " |")
    return lines


def zero_table(rows: Sequence[Record]) -> list[str]:
    """Markdown: per row, events planning no pair, executing nothing (queue set, as submitted today), valid plans."""
    lines = ["| row | events | no pair planned | nothing executed via queue set | nothing executed as submitted "
             "today | plans the checker passed |", "|---|---|---|---|---|---|"]
    for s in _solvers(rows):
        z = zero_counts(rows, s)
        lines.append(f"| {s} | {z['events']} | {z['planned']} | {z['queue_set']} | {z['single_queue']} | "
                     f"{z['valid']} |")
    return lines


def _groups(rows: Sequence[Record], column: str, quartiles: bool) -> tuple[dict[str, str], list[str]]:
    """Event -> group label (the column's value, or its quartile over the events), and the labels in order."""
    values = {str(r["event"]): r.get(column) for r in rows}
    if not quartiles:
        labels = {e: str(v) for e, v in values.items() if v not in (None, "")}
        return labels, sorted(set(labels.values()))
    xs = {e: v for e, v in ((e, num(v)) for e, v in values.items()) if v is not None}
    if not xs:
        return {}, []
    edges = np.quantile(np.array(sorted(xs.values())), [0.25, 0.5, 0.75])
    names = [f"Q1 (≤ {edges[0]:.0f})", f"Q2 (≤ {edges[1]:.0f})", f"Q3 (≤ {edges[2]:.0f})", f"Q4 (> {edges[2]:.0f})"]
    labels = {e: names[int(np.searchsorted(edges, v, side="left"))] for e, v in xs.items()}
    return labels, [n for n in names if n in set(labels.values())]


def breakdown_table(rows: Sequence[Record], column: str, quartiles: bool) -> list[str]:
    """Markdown: per group of ``column``, each row's median executed coverage via the queue set and as submitted
    today, and its events executing nothing (queue set)."""
    labels, order = _groups(rows, column, quartiles)
    if not order:
        return [f"(no {column})"]
    solvers = _solvers(rows)
    lines = ["| " + column + " | events | " + " | ".join(f"{s}: median queue set / today (zero)" for s in solvers)
             + " |", "|" + "---|" * (2 + len(solvers))]
    for g in order:
        sub = [r for r in rows if labels.get(str(r["event"])) == g]
        cells = []
        for s in solvers:
            q = list(metric_values(sub, s, "coverage_executed").values())
            t = list(metric_values(sub, s, "coverage_executed_single_queue").values())
            z = zero_counts(sub, s)["queue_set"]
            cells.append(f"{_fmt(float(np.median(q)) if q else None)} / {_fmt(float(np.median(t)) if t else None)}"
                         f" ({z})")
        lines.append(f"| {g} | {len({str(r['event']) for r in sub})} | " + " | ".join(cells) + " |")
    return lines


def commits_of(rows: Sequence[Record]) -> dict[str, int]:
    """Commit -> rows it planned (``(not recorded)`` for a row without one)."""
    commits: dict[str, int] = {}
    for r in rows:
        c = str(r.get("commit") or "") or "(not recorded)"
        commits[c] = commits.get(c, 0) + 1
    return commits


def _provenance(rows: Sequence[Record], n_all: int, missing: Mapping[str, list[str]], expected: set[str],
                every: Sequence[Record]) -> list[str]:
    """The header: a warning when the rows (``every``) are not from one commit, events tabulated of all, the
    commits, the events left out and the rows they lack."""
    commits = commits_of(every)
    out = []
    if len(commits) > 1 or any(c == "(not recorded)" or c.endswith("-dirty") for c in commits):
        out += [f"**WARNING: NOT ONE FROZEN RELEASE. These rows come from {len(commits)} commit(s) "
                + ", ".join(f"`{c}`" for c in sorted(commits)) + " (or from code with uncommitted changes, or from "
                "rows that do not record their commit); the tables mix the code of every one of them.**", ""]
    n = len({str(r["event"]) for r in rows})
    out.append(f"{n} events with a row of every row name (of {n_all}); {len(rows)} (event, row) rows; planned by "
               + (", ".join(f"`{c}` ({k} rows)" for c, k in sorted(commits_of(rows).items())) or "(none)") + ".")
    if missing:
        names = [s for s in RELEASE_ROWS if s in expected] + sorted(expected - set(RELEASE_ROWS))
        out += ["", f"{len(missing)} event(s) of {n_all} lack a row (of {', '.join(names)}) and are left "
                "out of every table below, paired differences included (a partial run: their rows are not all "
                "done): " + "; ".join(f"{e} (no {', '.join(m)})" for e, m in missing.items()) + "."]
    return out


def release_tables(rows: Sequence[Record], draws: int = 2000, seed: int = 0,
                   expected: Sequence[str] | None = None, curves: Mapping[tuple[str, str], Any] | None = None,
                   failed: Sequence[tuple[str, str]] = ()) -> str:
    """Every table of the release (Markdown) from population rows (module notes).

    ``expected``: the row names every tabulated event must have (default: those present in ``rows``; the
    release passes :data:`RELEASE_ROWS`); the events lacking one are listed in the header and left out.
    ``curves``, ``failed``: our rows' executed curves and the plans not reproduced
    (:func:`~.matched_tables.read_curves`); given, the matched-time section follows the paired differences
    (:func:`~.matched_tables.matched_tables`).
    """
    every = list(rows)
    n_all = len({str(r["event"]) for r in rows})
    missing = incomplete_events(rows, expected)
    names = _expected(rows, expected)
    rows = release_events(rows, expected)
    out = _provenance(rows, n_all, missing, names, every) + [
        "", f"Intervals: bootstrap over events, {draws} resamples, seed {seed}, 2.5th-97.5th percentiles. "
        "\"As submitted today\": the plan as one list queue valid over its horizon, its exposures in plan order "
        "(what SkyPortal's ZTF API sends for an observation plan).", "",
        "## Each row: mean [95 %] / median [95 %]", ""]
    out += metric_table(rows, draws, seed)
    out += ["", f"## Per-event paired differences against {REFERENCE}: mean [95 %] / median [95 %] "
                f"(better/worse/tied beyond {TIE:g} of n events)", ""]
    out += paired_table(rows, REFERENCE, draws, seed)
    if curves is not None:
        from .matched_tables import matched_tables

        out += [""] + matched_tables(rows, curves, failed, draws, seed)
    out += ["", "## Events where a row executes nothing", ""]
    out += zero_table(rows)
    for column, quartiles in (("event_class", False), ("distance_mpc", True), ("area90_deg2", True)):
        out += ["", f"## By {column}" + (" (quartiles over the events)" if quartiles else ""), ""]
        out += breakdown_table(rows, column, quartiles)
    return "\n".join(out) + "\n"
