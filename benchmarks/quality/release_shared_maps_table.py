#!/usr/bin/env python3
"""The shared-map release table from one ``mushrooms bench`` CSV: every metric with its spread, paired per map.

    .venv/bin/python benchmarks/quality/release_shared_maps_table.py RESULTS.csv [-o TABLES.md]
        [--reference greedy] [--exclude SUBSTRING ...] [--draws 2000] [--seed 0]

Per row (``service``, ``greedy``, ``hybrid``, ... as the CSV holds them): the mean and the median over the maps of
planned coverage (checker; and by the pair rule), executed coverage through the queue set (on time; 15, 30,
60 min late), executed as submitted today (one list queue), coverage / certified bound, and the scoring the
planner does not optimise (two detections >= 15 min apart on the executed record, Bulla 2019 grid, SFD dust;
campaign depth 20.8, perturbed execution, ztf_sim's depth), each with a percentile bootstrap 95 % interval
over maps (``mushrooms.evaluation.study.release_tables.bootstrap_interval``, seeded: the same table every run).
Then the per-map paired differences ``row - reference`` (mean, median, both with intervals; maps better / worse
/ tied beyond 1e-4), the sums executed / planned (the figure earlier READMEs quoted as "x0.99"), the maps a row
executes nothing on, the maps where the first row executes less than the reference, and the commits.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from mushrooms.evaluation.study.release_tables import bootstrap_interval

#: (column, label) in table order.
METRICS = (
    ("coverage", "planned (checker)"),
    ("coverage_pairs", "planned (pair rule)"),
    ("coverage_as_executed", "executed, queue set, on time"),
    ("coverage_late_15", "executed, queue set, 15 min late"),
    ("coverage_late_30", "executed, queue set, 30 min late"),
    ("coverage_late_60", "executed, queue set, 60 min late"),
    ("coverage_single_queue", "executed as submitted today (one list queue)"),
    ("coverage_over_bound", "planned / certified bound"),
    ("efficiency_two_detections", "2 detections >= 15 min (campaign depth 20.8)"),
    ("efficiency_one_detection", "1 detection (campaign depth 20.8)"),
    ("efficiency_two_detections_perturbed", "2 detections, overheads +-20 % and weather"),
    ("efficiency_two_detections_ztf_sim", "2 detections, ztf_sim depth"),
    ("efficiency_two_detections_mushrooms", "2 detections, the planner's depth"),
    ("open_shutter_s", "open shutter planned (h)"),
)
TIE = 1e-4


def num(x: str | None) -> float | None:
    try:
        v = float(x) if x not in (None, "") else None
    except ValueError:
        return None
    return v if v is None or np.isfinite(v) else None


def read(path: Path, exclude: list[str]) -> dict[str, dict[str, dict]]:
    """solver -> map -> row (only the maps every solver has)."""
    rows: dict[str, dict[str, dict]] = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            if any(e in r["skymap"] for e in exclude):
                continue
            rows.setdefault(r["solver"], {})[r["skymap"]] = r
    common = set.intersection(*(set(m) for m in rows.values())) if rows else set()
    return {s: {m: r for m, r in maps.items() if m in common} for s, maps in rows.items()}


def values(rows: dict[str, dict], column: str) -> dict[str, float]:
    scale = 1 / 3600 if column == "open_shutter_s" else 1.0
    return {m: v * scale for m, r in rows.items() if (v := num(r.get(column))) is not None}


def cell(x: list[float], draws: int, seed: int, sign: bool = False) -> str:
    if not x:
        return "-"
    f = "+.4f" if sign else ".4f"
    out = []
    for stat in (np.mean, np.median):
        ci = bootstrap_interval(x, stat, draws, seed)
        s = format(float(stat(x)), f)
        out.append(s + (f" [{format(ci[0], f)}, {format(ci[1], f)}]" if ci else ""))
    return " / ".join(out)


def tables(rows: dict[str, dict[str, dict]], reference: str, draws: int, seed: int) -> str:
    solvers = list(rows)
    first = solvers[0]
    maps = sorted(rows[first])
    out = [f"maps: {len(maps)}; rows: {', '.join(solvers)}; commits: "
           + ", ".join(sorted({r.get('commit', '') for s in solvers for r in rows[s].values()})), "",
           "Mean [bootstrap 95 %] / median [bootstrap 95 %] over the maps with a value (n):", "",
           "| metric | " + " | ".join(f"{s}" for s in solvers) + " |", "|---|" + "---|" * len(solvers)]
    for col, label in METRICS:
        cells = []
        for s in solvers:
            v = list(values(rows[s], col).values())
            cells.append(f"{cell(v, draws, seed)} (n {len(v)})")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    out += ["", f"Per-map paired differences, row - {reference} (mean [95 %] / median [95 %]; maps better / worse / "
            f"tied beyond {TIE}):", "", "| metric | " + " | ".join(f"{s} - {reference}" for s in solvers
                                                                    if s != reference) + " |",
            "|---|" + "---|" * (len(solvers) - 1)]
    for col, label in METRICS:
        cells = []
        for s in solvers:
            if s == reference:
                continue
            a, b = values(rows[s], col), values(rows[reference], col)
            d = [a[m] - b[m] for m in a if m in b]
            tally = f" ({sum(x > TIE for x in d)}/{sum(x < -TIE for x in d)}/{sum(abs(x) <= TIE for x in d)} of {len(d)})"
            cells.append(cell(d, draws, seed, sign=True) + tally)
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    out += ["", "Sums over the maps, executed / planned (checker coverage):", "",
            "| row | queue set on time | 15 min late | 30 min late | 60 min late | as submitted today | "
            "maps executing nothing (queue set / today) of maps planning something |", "|---|---|---|---|---|---|---|"]
    for s in solvers:
        planned = values(rows[s], "coverage")
        tot = sum(planned.values())
        ratios = []
        for col in ("coverage_as_executed", "coverage_late_15", "coverage_late_30", "coverage_late_60",
                    "coverage_single_queue"):
            v = values(rows[s], col)
            ratios.append(f"x{sum(v.values()) / sum(planned[m] for m in v):.3f}" if v else "-")
        some = [m for m, c in planned.items() if c > 0]
        zq = sum(values(rows[s], "coverage_as_executed").get(m, 0.0) <= 1e-9 for m in some)
        zs = sum(values(rows[s], "coverage_single_queue").get(m, 0.0) <= 1e-9 for m in some)
        out.append(f"| {s} (planned sum {tot:.3f}) | " + " | ".join(ratios) + f" | {zq} / {zs} of {len(some)} |")
    for s in solvers:
        if s == reference:
            continue
        a, b = values(rows[s], "coverage_as_executed"), values(rows[reference], "coverage_as_executed")
        worse = sorted((a[m] - b[m], m) for m in a if m in b and a[m] - b[m] < -TIE)
        out += ["", f"Maps where {s} executes less than {reference} (queue set, on time, beyond {TIE}): {len(worse)}"
                + ("" if not worse else ": " + ", ".join(f"{m} {d:+.4f}" for d, m in worse))]
    return "\n".join(out) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", type=Path)
    ap.add_argument("-o", "--out", type=Path)
    ap.add_argument("--reference", default="greedy")
    ap.add_argument("--exclude", nargs="*", default=[], help="leave out maps whose path contains one of these")
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if not args.csv.is_file():
        print(f"{args.csv}: no such file", file=sys.stderr)
        return 2
    rows = read(args.csv, args.exclude)
    if args.reference not in rows:
        print(f"{args.csv}: no row {args.reference!r}", file=sys.stderr)
        return 2
    text = tables(rows, args.reference, args.draws, args.seed)
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
