"""A population's tables from its ``results.csv`` (:mod:`.population_rows`): the papers' layouts.

* the MUSHROOMS paper's Tables 2-3 (:func:`~.tables.paper_tables`, reused
  on the rows read back as bench rows, events as maps);
* paired differences of ours against each baseline present (greedy,
  gwemopt raw, gwemopt rule-repaired): mean difference and its standard
  error over the events both planned, events better / worse;
* LUMOS's headline metric (Wagh et al. 2026, arXiv 2601.08912): the mean
  cumulative probability (coverage) of a solver relative to gwemopt's,
  ``100 (mean cov_s / mean cov_gwemopt - 1)`` % over the events both planned,
  on the planned coverage and on ``coverage_executed`` (as ZTF would execute
  the queues);
* planned against executed coverage per solver;
* the same means by event class, by distance and by 90 % area (quartiles).
"""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

from ..bench.compare import TIE_COVERAGE, TIE_EFFICIENCY, by_map, scored
from ..bench.rows import num
from .tables import comparison_pair, paper_tables

__all__ = ["EFFICIENCY_KEYS", "as_bench_rows", "complete_events", "paired_differences", "lumos_metric",
           "lumos_interval", "breakdown",
           "executed_table", "population_tables"]

Record = dict[str, Any]

#: The three light curves of the population's columns.
EFFICIENCY_KEYS = ("optimistic", "conservative", "nsbh")
#: Baselines of the paired comparison, in this order.
BASELINES = ("greedy", "gwemopt", "gwemopt-repaired")
#: LUMOS's published value of its metric (+84.7 % over gwemopt on 1199 O4 events).
LUMOS_PUBLISHED_PERCENT = 84.7
#: How this metric differs from LUMOS's (said beside it, not hidden).
LUMOS_METHOD = (
    "Not LUMOS's experiment: (1) the population is this recipe's (`o4`, its deviations in provenance.md), not "
    "their 1199 O4 events; (2) gwemopt is 0.4.2 run as `mushrooms bench` runs it (`--scheduleType greedy "
    "--timeallocationType powerlaw --doChipGaps --doSingleExposure --doAlternatingFilters`, MOC tiles, the "
    "configuration's filters, 300 s exposures, airmass limit and 24 h horizon), not their settings; (3) "
    "`coverage` is the probability inside the fields a plan observes at all (exact footprints) - for our plans, "
    "which the checker makes pair every field, the same as both filters the cadence apart, but raw gwemopt's "
    "schedules break the rules (windows, slews, pairs) and are counted as they are; `as executed` counts only "
    "fields the telescope model's run of the ZTF queues observes in both filters at least the cadence apart; "
    "(4) the mean is over the events both planned; the band is a seeded bootstrap over events.")


def as_bench_rows(rows: Sequence[Mapping[str, Any]]) -> list[Record]:
    """Population rows as the bench's (``skymap`` = the event; the bound's ratio recomputed)."""
    out = []
    for r in rows:
        d = dict(r)
        d["skymap"] = r["event"]
        d["bound"] = r.get("upper_bound")
        d["coverage_as_executed"] = r.get("coverage_executed")
        cov, bound = num(r.get("coverage")), num(r.get("upper_bound"))
        d["coverage_over_bound"] = cov / bound if cov is not None and bound else None
        out.append(d)
    return out


def _paired(rows: Sequence[Mapping[str, Any]], a: str, b: str, key: str, tie: float) -> tuple[int, str]:
    """(events, ``mean ± se (better/worse)``) of ``key`` of ``a`` minus ``b`` over the events both scored."""
    diffs = []
    for sol in by_map(rows).values():
        ra, rb = sol.get(a), sol.get(b)
        if scored(ra) and scored(rb):
            x, y = num(ra.get(key)), num(rb.get(key))
            if x is not None and y is not None:
                diffs.append(x - y)
    n = len(diffs)
    if not n:
        return 0, "-"
    mean = sum(diffs) / n
    se = math.sqrt(sum((d - mean) ** 2 for d in diffs) / (n - 1) / n) if n > 1 else float("nan")
    better, worse = sum(d > tie for d in diffs), sum(d < -tie for d in diffs)
    return n, f"{mean:+.4f} ± {se:.4f} ({better}/{worse})"


def paired_differences(rows: Sequence[Mapping[str, Any]], ours: Sequence[str]) -> list[str]:
    """Markdown: per (ours, baseline) pair, paired differences of coverage and each efficiency."""
    solvers = set(str(r["solver"]) for r in rows)
    keys = [("coverage", TIE_COVERAGE), ("coverage_executed", TIE_COVERAGE)] + [
        (f"efficiency_{k}", TIE_EFFICIENCY) for k in EFFICIENCY_KEYS]
    head = ["A − B", "events"] + [k.replace("efficiency_", "eff. ") for k, _ in keys]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for a in ours:
        for b in BASELINES:
            if a == b or a not in solvers or b not in solvers:
                continue
            cells = [_paired(rows, a, b, k, tie) for k, tie in keys]
            lines.append("| " + " | ".join([f"{a} − {b}", str(cells[0][0])] + [c for _, c in cells]) + " |")
    return lines


def lumos_pairs(rows: Sequence[Mapping[str, Any]], solver: str, reference: str = "gwemopt",
                key: str = "coverage") -> list[tuple[float, float]]:
    """``(solver's, reference's)`` ``key`` per event both planned (and both have ``key``)."""
    pairs = []
    for sol in by_map(rows).values():
        ra, rb = sol.get(solver), sol.get(reference)
        if scored(ra) and scored(rb) and num(ra.get(key)) is not None and num(rb.get(key)) is not None:
            pairs.append((num(ra[key]), num(rb[key])))
    return pairs


def lumos_metric(rows: Sequence[Mapping[str, Any]], solver: str, reference: str = "gwemopt",
                 key: str = "coverage") -> tuple[int, float | None]:
    """(events, percent): mean ``key`` (coverage) of ``solver`` relative to ``reference``'s over the events both
    planned (and both have ``key``)."""
    pairs = lumos_pairs(rows, solver, reference, key)
    if not pairs:
        return 0, None
    base = sum(b for _, b in pairs)
    return len(pairs), (100.0 * (sum(a for a, _ in pairs) / base - 1.0) if base > 0 else None)


def lumos_interval(rows: Sequence[Mapping[str, Any]], solver: str, reference: str = "gwemopt",
                   key: str = "coverage", draws: int = 2000, seed: int = 0) -> tuple[float, float] | None:
    """The 16th and 84th percentiles (%) of :func:`lumos_metric` over the events resampled with replacement
    (a seeded bootstrap: the metric's spread from which events happen to be in the population)."""
    import numpy as np

    pairs = lumos_pairs(rows, solver, reference, key)
    if len(pairs) < 2:
        return None
    a, b = np.array(pairs, dtype=float).T
    pick = np.random.default_rng(seed).integers(0, len(pairs), size=(draws, len(pairs)))
    base = b[pick].sum(axis=1)
    ratio = 100.0 * (a[pick].sum(axis=1)[base > 0] / base[base > 0] - 1.0)
    if not ratio.size:
        return None
    lo, hi = np.percentile(ratio, [16, 84])
    return float(lo), float(hi)


def _quartile_label(value: float | None, edges: Sequence[float]) -> str | None:
    if value is None:
        return None
    k = sum(value > e for e in edges)
    return f"Q{k + 1}"


def breakdown(rows: Sequence[Mapping[str, Any]], column: str, quartiles: bool) -> list[str]:
    """Markdown: mean coverage and optimistic efficiency per solver within each group of ``column``
    (its values, or its quartiles over the events)."""
    per_event = {r["event"]: num(r.get(column)) if quartiles else r.get(column) for r in rows}
    edges: list[float] = []
    if quartiles:
        xs = sorted(v for v in per_event.values() if v is not None)
        if not xs:
            return [f"(no {column})"]
        edges = [xs[min(len(xs) - 1, int(q * len(xs)))] for q in (0.25, 0.5, 0.75)]
    group = {e: (_quartile_label(v, edges) if quartiles else v) for e, v in per_event.items()}
    solvers = list(dict.fromkeys(str(r["solver"]) for r in rows))
    groups = sorted({g for g in group.values() if g is not None})
    lines = ["| " + " | ".join([column, "events"] + [f"{s} cov / eff. opt." for s in solvers]) + " |",
             "|" + "---|" * (2 + len(solvers))]
    for g in groups:
        cells = [str(g) + (f" (≤ {edges[int(g[1]) - 1]:.0f})" if quartiles and int(g[1]) <= 3 else ""),
                 str(sum(1 for v in group.values() if v == g))]
        for s in solvers:
            rs = [r for r in rows if r["solver"] == s and group.get(r["event"]) == g and scored(r)]
            cov = [num(r["coverage"]) for r in rs]
            eff = [x for x in (num(r.get("efficiency_optimistic")) for r in rs) if x is not None]
            cells.append(f"{sum(cov) / len(cov):.3f} / {sum(eff) / len(eff):.3f}" if cov and eff else "-")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def executed_table(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Markdown: per solver, mean planned and executed coverage over its events with both, their ratio, the plans
    the checker passed and the ``not_observable`` answers (the service's, below ``min_coverage``: scored as 0)."""
    lines = ["| solver | events | coverage | coverage_executed | executed / planned | valid plans | not observable |",
             "|---|---|---|---|---|---|---|"]
    for s in dict.fromkeys(str(r["solver"]) for r in rows):
        pairs = [(num(r["coverage"]), num(r.get("coverage_executed"))) for r in rows
                 if r["solver"] == s and scored(r) and num(r.get("coverage_executed")) is not None]
        valid = sum(1 for r in rows if r["solver"] == s and r.get("valid") is True)
        answers = sum(1 for r in rows if r["solver"] == s and r.get("status") == "not_observable")
        if not pairs:
            lines.append(f"| {s} | 0 | - | - | - | {valid} | {answers} |")
            continue
        cov, ex = sum(a for a, _ in pairs) / len(pairs), sum(b for _, b in pairs) / len(pairs)
        lines.append(f"| {s} | {len(pairs)} | {cov:.4f} | {ex:.4f} | {ex / cov if cov > 0 else float('nan'):.3f} "
                     f"| {valid} | {answers} |")
    return lines


def complete_events(rows: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The rows of the events that have a row of every solver present (a partial run's comparable set)."""
    solvers = set(str(r["solver"]) for r in rows)
    have: dict[str, set[str]] = {}
    for r in rows:
        have.setdefault(str(r["event"]), set()).add(str(r["solver"]))
    return [r for r in rows if have[str(r["event"])] == solvers]


def population_tables(rows: Sequence[Mapping[str, Any]]) -> str:
    """Every table of a population's results (Markdown), from :data:`~.population_rows.POPULATION_COLUMNS` rows.

    Only the events with a row of every solver are tabulated (while a run
    is partial, later events may have greedy's row alone); the first line
    says how many of how many.
    """
    n_all = len({r["event"] for r in rows})
    rows = complete_events(rows)
    bench_rows = as_bench_rows(rows)
    solvers = list(dict.fromkeys(str(r["solver"]) for r in rows))
    ours = [s for s in solvers if s not in BASELINES] or ([comparison_pair(solvers)[0]] if solvers else [])
    executed = sum(1 for r in rows if num(r.get("coverage_executed")) is not None)
    out = [f"{len(by_map(bench_rows))} events with every solver's row (of {n_all}), {len(rows)} (event, solver) "
           f"rows; coverage_executed (as ZTF would execute the queues) filled on {executed}.", "",
           "## The MUSHROOMS paper's Tables 2-3 layout", "", paper_tables(bench_rows, EFFICIENCY_KEYS), "",
           "## Paired differences (A − B: mean ± standard error over the events both planned; "
           "events better/worse beyond the tie margins)", ""]
    out += paired_differences(bench_rows, ours + (["greedy"] if "greedy" in solvers else []))
    out += ["", "## LUMOS's metric: mean cumulative probability relative to gwemopt "
                f"(LUMOS published +{LUMOS_PUBLISHED_PERCENT} % on 1199 O4 events)", "", LUMOS_METHOD, ""]
    for s in solvers:
        if s == "gwemopt":
            continue
        cells = []
        for key, label in (("coverage", ""), ("coverage_executed", "as executed ")):
            n, pct = lumos_metric(bench_rows, s, key=key)
            if pct is None:
                continue
            band = lumos_interval(bench_rows, s, key=key)
            cells.append(f"{label}{pct:+.1f} %" + (f" (bootstrap 68 %: {band[0]:+.1f} to {band[1]:+.1f})"
                                                    if band else "") + f" over {n} events")
        out.append(f"- {s}: " + ("; ".join(cells) or "no event with a gwemopt row"))
    out += ["", "## Planned and executed coverage (the queues run by the telescope model, cadence-valid pairs)", ""]
    out += executed_table(bench_rows)
    for column, quartiles in (("event_class", False), ("distance_mpc", True), ("area90_deg2", True)):
        out += ["", f"## By {column}" + (" (quartiles over the events)" if quartiles else ""), ""]
        out += breakdown(bench_rows, column, quartiles)
    return "\n".join(out)
