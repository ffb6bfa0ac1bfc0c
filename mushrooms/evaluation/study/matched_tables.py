"""The release's matched-time tables (issue 55 item 2): each of our rows at gwemopt's open-shutter time, per event.

Input: the population rows (:data:`~.population_rows.POPULATION_COLUMNS`) and
the executed curves of our rows (:func:`~mushrooms.evaluation.matched_time.executed_curve`
per (event, row), read by :func:`read_curves`).  For an event, a row and a
baseline, the **budget** is the baseline's ``open_shutter_executed_s`` (the
exposure seconds its queue set had done, executed on time), the row's
**matched coverage** is :func:`~mushrooms.evaluation.matched_time.coverage_at`
its curve at that budget (the time-ordered prefix of its executed records
within the budget, by the pair rule), compared with the baseline's
``coverage_executed`` (the same executor, the same pair rule, its whole
plan).  Output (Markdown): the matched coverages beside the baseline's, and
the per-event paired differences (row at the baseline's time minus the
baseline), means and medians with bootstrap 95 % intervals and the events
better / worse / tied.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..bench.rows import num
from ..matched_time import coverage_at
from .release_stats import TIE, cell, metric_values, summary

__all__ = ["MATCHED_ROWS", "BASELINES", "read_curves", "write_curves", "matched_coverages", "matched_differences",
           "matched_tables"]

Record = Mapping[str, Any]
Curves = Mapping[tuple[str, str], Mapping[str, np.ndarray]]
#: The two readings of a row at a budget: its curve's key -> the file's field.
KINDS = {"prefix": "curve", "subset": "subset"}

#: Our rows read at a baseline's time, in table order.
MATCHED_ROWS = ("service", "service-grg", "greedy")
#: Events the release is to have (issue 55 item 5): below, the section says its numbers are partial.
RELEASE_EVENTS = 250
#: The rows whose open-shutter time is the budget: gwemopt as ZTF ran it in O4, and SkyPortal's defaults.
BASELINES = ("gwemopt-o4", "gwemopt-skyportal")


def write_curves(entries: Sequence[Mapping[str, Any]], path: str | Path) -> None:
    """One JSON line per (event, row): ``event``, ``solver``, ``reproduced``, ``curve`` (time-ordered prefix,
    :func:`~mushrooms.evaluation.matched_time.executed_curve`) and ``subset`` (covered fields best first,
    :func:`~mushrooms.evaluation.matched_time.subset_curve`), each an (n + 1, 2) list; gzipped without a name or
    time in the header, so the same entries give the same bytes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as fh:
        for e in entries:
            fh.write((json.dumps(dict(e), sort_keys=True) + "\n").encode())


def read_curves(path: str | Path) -> tuple[dict[tuple[str, str], dict[str, np.ndarray]], list[tuple[str, str]]]:
    """The curves of :func:`write_curves` whose plan was reproduced ((event, solver) -> ``prefix`` and ``subset``
    (n + 1, 2) arrays), and the (event, solver) whose plan was not (left out of the tables)."""
    curves, failed = {}, []
    with gzip.open(path, "rt") as fh:
        for line in fh:
            e = json.loads(line)
            key = (str(e["event"]), str(e["solver"]))
            if e.get("reproduced") and e.get("curve") is not None and e.get("subset") is not None:
                curves[key] = {k: np.asarray(e[c], dtype=float).reshape(-1, 2) for k, c in KINDS.items()}
            else:
                failed.append(key)
    return curves, failed


def matched_coverages(rows: Sequence[Record], curves: Curves, solver: str, baseline: str,
                      kind: str = "prefix") -> dict[str, tuple[float, float, float]]:
    """Event -> (``solver``'s coverage at ``baseline``'s open-shutter time, ``baseline``'s executed coverage, the
    budget in s), over the events with a curve of ``solver`` and both numbers of ``baseline``; ``kind``:
    ``prefix`` (time-ordered prefix) or ``subset`` (covered fields best first)."""
    budget = metric_values(rows, baseline, "open_shutter_executed_s")
    theirs = metric_values(rows, baseline, "coverage_executed")
    out = {}
    for event in sorted(set(budget) & set(theirs)):
        curve = curves.get((event, solver))
        if curve is not None:
            out[event] = (coverage_at(curve[kind], budget[event]), theirs[event], budget[event])
    return out


def matched_differences(rows: Sequence[Record], curves: Curves, solver: str, baseline: str,
                        kind: str = "prefix") -> dict[str, float]:
    """Event -> ``solver`` at ``baseline``'s open-shutter time (``kind``) minus ``baseline`` (executed coverage)."""
    return {e: ours - theirs
            for e, (ours, theirs, _) in matched_coverages(rows, curves, solver, baseline, kind).items()}


def _tally(d: Sequence[float]) -> str:
    return (f" ({sum(x > TIE for x in d)}/{sum(x < -TIE for x in d)}/{sum(abs(x) <= TIE for x in d)} of {len(d)})"
            if d else "")


def _full(rows: Sequence[Record], solver: str, column: str, events: Sequence[str], scale: float = 1.0) -> list[float]:
    values = metric_values(rows, solver, column, scale)
    return [values[e] for e in events if e in values]


def matched_table(rows: Sequence[Record], curves: Curves, draws: int = 2000, seed: int = 0) -> list[str]:
    """Markdown: per baseline and row, the row's coverage at the baseline's time, its whole-plan coverage and
    open-shutter time, and the baseline's, over the same events: mean [95 %] / median [95 %]."""
    lines = ["| row at the baseline's open-shutter time | events | budget: baseline's open shutter executed (h) | "
             "row, time-ordered prefix within the budget | row, covered fields best first within the budget | "
             "baseline, its whole plan | row, its whole plan | row's open shutter executed (h) |",
             "|---|---|---|---|---|---|---|---|"]
    for base in BASELINES:
        for s in MATCHED_ROWS:
            m = matched_coverages(rows, curves, s, base)
            if not m:
                continue
            ev = sorted(m)
            best = matched_coverages(rows, curves, s, base, "subset")
            cells = [cell(summary([m[e][2] / 3600.0 for e in ev], draws, seed), 2),
                     cell(summary([m[e][0] for e in ev], draws, seed)),
                     cell(summary([best[e][0] for e in ev], draws, seed)),
                     cell(summary([m[e][1] for e in ev], draws, seed)),
                     cell(summary(_full(rows, s, "coverage_executed", ev), draws, seed)),
                     cell(summary(_full(rows, s, "open_shutter_executed_s", ev, 1 / 3600.0), draws, seed), 2)]
            lines.append(f"| {s} at {base}'s | {len(ev)} | " + " | ".join(cells) + " |")
    return lines


def matched_paired_table(rows: Sequence[Record], curves: Curves, draws: int = 2000, seed: int = 0) -> list[str]:
    """Markdown: per baseline and row, the per-event difference (row at the baseline's time minus the baseline,
    executed coverage): mean [95 %] / median [95 %] (better/worse/tied), and the same at full time."""
    lines = ["| row − baseline (executed via queue set) | at the baseline's open-shutter time: time-ordered prefix | "
             "at the baseline's open-shutter time: covered fields best first | each at its own time |",
             "|---|---|---|---|"]
    for base in BASELINES:
        for s in MATCHED_ROWS:
            d = matched_differences(rows, curves, s, base)
            if not d:
                continue
            ours = metric_values(rows, s, "coverage_executed")
            theirs = metric_values(rows, base, "coverage_executed")
            full = [ours[e] - theirs[e] for e in sorted(d) if e in ours and e in theirs]
            best = list(matched_differences(rows, curves, s, base, "subset").values())
            cells = [cell(summary(list(d.values()), draws, seed), sign=True) + _tally(list(d.values())),
                     cell(summary(best, draws, seed), sign=True) + _tally(best),
                     cell(summary(full, draws, seed), sign=True) + _tally(full)]
            lines.append(f"| {s} − {base} | " + " | ".join(cells) + " |")
    return lines


#: What the matched tables are, said above them.
MATCHED_NOTE = (
    "Post-processing of the frozen rows, not a run of its own: the study's records keep metrics, not plans, so "
    "the plans of {rows} were made again with the frozen code (`benchmarks/science/population_o4_replan.py`: the "
    "study's own path on the deterministic budget, gwemopt's from the run's cache) and kept only where every value "
    "the record has of the plan (planned and executed coverage, open-shutter seconds, exposures) came out the "
    "same; {kept}. Each plan's queue set is executed on time by the executor of the column \"executed via queue "
    "set\" and scored by the same pair rule after every done exposure, in time order "
    "(`mushrooms.evaluation.matched_time`, `study/executed_curves.jsonl.gz`). Matched on open-shutter time: a row's "
    "coverage at a baseline's time is that of its executed records' time-ordered prefix whose open-shutter "
    "seconds do not exceed the baseline's on the event (the budget: the baseline's exposures done, executed on "
    "time). The prefix of the service's executed plan is a conservative stand-in for a planner given less time: "
    "a planner given the budget would choose its fields for it, the prefix keeps those the whole plan took first, "
    "with the first visits whose pair comes later. A tighter stand-in, still a sub-schedule of what was executed: "
    "the fields the executed record covers, taken best first (probability gained per open-shutter second, each "
    "field's done exposures at the times they ran) until the budget; it is not run through the executor again, "
    "and the executor's gaps would let a shorter plan start its pairs sooner. Both are lower bounds of a planner "
    "given the budget, up to that planner's optimality. "
    "Open shutter, not telescope time: gwemopt-o4's 180 s exposures in g-r-g pay the same slew, readout and "
    "filter changes as a 300 s one, so at equal open-shutter time gwemopt used more of the telescope. The "
    "like-for-like row against gwemopt-o4 is service-grg (the same g-r-g sequence at 180 s: the third visit costs "
    "both the same shutter time and counts in neither's pair-rule coverage); the service (g-r at 300 s) spends no "
    "time on a third visit. For the next run: each record should keep its executed curve (or its plan), so that "
    "no plan has to be made again, and a row planned under the budget itself (the service with an open-shutter "
    "cap equal to gwemopt's on the event, a constraint the frozen code does not have: see 'Under gwemopt-o4's "
    "budget, planned' below) replaces both stand-ins by the planner.")

#: The reverse caveat: what gwemopt's own command lines leave unused (``mushrooms.evaluation.gwemopt_options``).
GWEMOPT_CAVEAT = (
    "The reverse caveat: gwemopt's shorter time is its command line's, not the sky's. gwemopt-o4 (skyportal#4206's "
    "line) keeps the 15 most probable tiles (`--max_nb_tiles 15`) and gives each three 180 s visits (`--filters "
    "g,r,g --exposuretimes 180,180,180`): at most 15 x 3 x 180 s = 2.25 h of open shutter, whatever the night "
    "offers (its median planned open shutter is that cap); `--doBalanceExposure` then drops the tiles not observed "
    "in every visit, `--airmass 2.5` and the night bound the rest, and `--mindiff 30` (seconds) changes nothing. "
    "gwemopt-skyportal has no tile cap but tiles only the fields touching the 90 % credible region (what SkyPortal "
    "hands gwemopt), above airmass 2.0, three 300 s visits g-r-g, balanced: its time ends with those fields' "
    "observable slots. Neither is given more time here: the tables ask only whether our rows' lead survives when "
    "each is held to gwemopt's open-shutter time on every event, not what gwemopt would do with the service's.")


def matched_tables(rows: Sequence[Record], curves: Curves, failed: Sequence[tuple[str, str]] = (),
                   draws: int = 2000, seed: int = 0) -> list[str]:
    """The matched-time section (Markdown lines): its notes, the coverages and the paired differences.

    ``rows``: the release's (complete) events; ``curves`` and ``failed`` from :func:`read_curves`.
    """
    events = {str(r["event"]) for r in rows}
    kept = {k: v for k, v in curves.items() if k[0] in events}
    lost = sorted(k for k in failed if k[0] in events)
    n_plans = len(events) * len(MATCHED_ROWS)
    text = (f"{len(kept)} of {n_plans} plans of {', '.join(MATCHED_ROWS)} on the {len(events)} events reproduced"
            + (f" (not: {'; '.join(f'{e} {s}' for e, s in lost)})" if lost else "")
            + (f"; {n_plans - len(kept) - len(lost)} not planned again" if n_plans - len(kept) - len(lost) else ""))
    out = ["## At matched telescope time: our rows at gwemopt's open-shutter time (executed via queue set)", ""]
    if len(events) < RELEASE_EVENTS:
        out += [f"**PARTIAL: {len(events)} of the release's >= {RELEASE_EVENTS} events; quote none of these "
                "numbers as a result.**", ""]
    out += [MATCHED_NOTE.format(rows=", ".join(MATCHED_ROWS), kept=text)]
    out += ["", GWEMOPT_CAVEAT]
    out += ["", "Coverage: mean [95 %] / median [95 %] over the events both rows have.", ""]
    out += matched_table(rows, kept, draws, seed)
    out += ["", f"Per-event paired differences: mean [95 %] / median [95 %] (better/worse/tied beyond {TIE:g} of n "
                "events).", ""]
    out += matched_paired_table(rows, kept, draws, seed)
    return out
