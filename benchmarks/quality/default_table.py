"""The default's paired table: four strategies on the same maps, quiet and loaded, and the split-half choice.

Reads the ``results.csv`` of ``benchmarks/quality/bench_grg.sh`` runs (one per machine
load) and writes a Markdown table per run:

* per strategy (``hybrid`` = fixed 300 s, ``hybrid@e180`` = fixed 180 s,
  ``hybrid@menu`` = the exposure menu, ``hybrid@grg`` = g-r-g at 180 s): the
  mean coverage (checker), expected detections (X1, exact) for the three
  light curves, ``coverage_as_executed`` (the executor's F1 credit);
* paired against fixed 300 s (the default today): mean difference ± its
  paired standard error over maps (``std(d) / sqrt(n)``), median, maps
  better / worse (beyond 1e-4 in coverage, 1e-3 in E);
* split halves: the maps in name order, even positions half A, odd half B;
  on each half the strategy expecting the most detections of the decision
  curve is *chosen*, and its paired difference against every other
  strategy is *reported on the other half*.

    python benchmarks/quality/default_table.py quiet=DIR/results.csv loaded=DIR2/results.csv [--curve conservative] \
        > benchmarks/results/quality/grg_default/table.md
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from mushrooms.evaluation.efficiency import paired_difference  # noqa: E402

ARMS = {"hybrid": "fixed 300 s", "hybrid@e180": "fixed 180 s", "hybrid@menu": "exposure menu",
        "hybrid@grg": "g-r-g 180 s"}
METRICS = {"coverage": ("coverage", 1e-4), "E opt": ("expected_optimistic", 1e-3),
           "E cons": ("expected_conservative", 1e-3), "E nsbh": ("expected_nsbh", 1e-3),
           "cov executed": ("coverage_as_executed", 1e-4)}
REFERENCE = "hybrid"
#: g-r-g planned by the hybrid (greedy + slot MILP) against greedy alone, when the run has both rows
GRG_STAGES = ("hybrid@grg", "greedy@grg")


def load(path: Path, arms=ARMS) -> dict[str, dict[str, dict[str, float]]]:
    """solver -> map name -> {column: value}, only maps every one of ``arms`` planned with a valid plan."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            if row["solver"] not in arms or row.get("valid") != "True":
                continue
            name = Path(row["skymap"]).name
            cols = {c: float(row[c] or "nan") for _, (c, _) in METRICS.items()}
            out.setdefault(row["solver"], {})[name] = dict(cols, runtime_s=float(row["runtime_s"]),
                                                           won=row["solver_detail"], stage=row["detection_stage"])
    common = set.intersection(*(set(v) for v in out.values())) if len(out) == len(arms) else set()
    return {s: {m: v[m] for m in sorted(common)} for s, v in out.items()} if common else {}


def values(table, solver: str, column: str, maps: list[str]) -> np.ndarray:
    return np.array([table[solver][m][column] for m in maps], float)


def fmt(diff: float, err: float, digits: int = 4) -> str:
    return f"{diff:+.{digits}f} ± {err:.{digits}f}" if math.isfinite(err) else f"{diff:+.{digits}f}"


def paired_rows(table, maps: list[str]) -> list[str]:
    """The per-strategy means and the paired differences against :data:`REFERENCE`."""
    head = "| strategy | " + " | ".join(METRICS) + " |"
    lines = [head, "|" + "---|" * (len(METRICS) + 1)]
    for s, label in ARMS.items():
        means = [f"{np.nanmean(values(table, s, c, maps)):.4f}" for c, _ in METRICS.values()]
        lines.append(f"| {label}, mean | " + " | ".join(means) + " |")
    for s, label in ARMS.items():
        if s == REFERENCE:
            continue
        cells, counts = [], []
        for c, tie in METRICS.values():
            d = values(table, s, c, maps) - values(table, REFERENCE, c, maps)
            diff, err = paired_difference(d, np.zeros_like(d))
            cells.append(fmt(diff, err))
            counts.append(f"{np.median(d):+.4f}; {int((d > tie).sum())} / {int((d < -tie).sum())}")
        lines.append(f"| {label} − 300 s, mean ± s.e. | " + " | ".join(cells) + " |")
        lines.append(f"| {label} − 300 s, median; better / worse | " + " | ".join(counts) + " |")
    return lines


def run_rows(table, maps: list[str]) -> list[str]:
    """Per strategy: the plan's median wall time (s) and which scheduler's plan was published, on how many maps."""
    lines = ["| strategy | wall time median (s) | published plan (maps) |", "|---|---|---|"]
    for s, label in ARMS.items():
        won: dict[str, int] = {}
        for m in maps:
            won[table[s][m]["won"]] = won.get(table[s][m]["won"], 0) + 1
        mix = ", ".join(f"{k} {v}" for k, v in sorted(won.items(), key=lambda kv: -kv[1]))
        lines.append(f"| {label} | {np.median([table[s][m]['runtime_s'] for m in maps]):.1f} | {mix} |")
    return lines


def stage_rows(path: Path) -> list[str]:
    """g-r-g: the hybrid's plan (greedy + slot MILP) against greedy's, paired (empty without a greedy@grg row)."""
    table = load(path, GRG_STAGES)
    if not table:
        return []
    maps = sorted(table[GRG_STAGES[0]])
    lines = [f"g-r-g, hybrid (greedy + slot MILP) − greedy, {len(maps)} maps:", "",
             "| | " + " | ".join(METRICS) + " |", "|" + "---|" * (len(METRICS) + 1)]
    cells, counts = [], []
    for c, tie in METRICS.values():
        d = values(table, GRG_STAGES[0], c, maps) - values(table, GRG_STAGES[1], c, maps)
        diff, err = paired_difference(d, np.zeros_like(d))
        cells.append(fmt(diff, err))
        counts.append(f"{int((d > tie).sum())} / {int((d < -tie).sum())}")
    lines.append("| mean ± s.e. | " + " | ".join(cells) + " |")
    lines.append("| better / worse | " + " | ".join(counts) + " |")
    return lines


def split_rows(table, maps: list[str], column: str) -> list[str]:
    """Choose on one half (most mean ``column``), report the choice's paired differences on the other."""
    halves = {"A": maps[0::2], "B": maps[1::2]}
    lines = [f"| chosen on | choice (mean {column} there) | reported on | its {column} there | "
             + " | ".join(f"− {ARMS[s]}" for s in ARMS) + " |", "|" + "---|" * (4 + len(ARMS))]
    for on, other in (("A", "B"), ("B", "A")):
        means = {s: float(np.mean(values(table, s, column, halves[on]))) for s in ARMS}
        pick = max(means, key=means.get)
        held = halves[other]
        cells = []
        for s in ARMS:
            if s == pick:
                cells.append("—")
                continue
            d = values(table, pick, column, held) - values(table, s, column, held)
            diff, err = paired_difference(d, np.zeros_like(d))
            cells.append(fmt(diff, err))
        lines.append(f"| {on} ({len(halves[on])}) | {ARMS[pick]} ({means[pick]:.4f}) | {other} ({len(held)}) | "
                     f"{np.mean(values(table, pick, column, held)):.4f} | " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", metavar="LABEL=CSV", help="a bench_grg.sh results.csv and its load label")
    p.add_argument("--curve", default="conservative", choices=["optimistic", "conservative", "nsbh"],
                   help="light curve the split-half choice is made on (default: the service's detection_lightcurve)")
    args = p.parse_args(argv)
    for spec in args.runs:
        label, _, path = spec.partition("=")
        table = load(Path(path))
        if not table:
            print(f"## {label}: no map with a valid plan of every strategy ({path})\n")
            continue
        maps = sorted(next(iter(table.values())))
        print(f"## {label}: {len(maps)} maps with a valid plan of all four strategies\n")
        print("\n".join(paired_rows(table, maps)) + "\n")
        print("\n".join(run_rows(table, maps)) + "\n")
        stages = stage_rows(Path(path))
        if stages:
            print("\n".join(stages) + "\n")
        for curve in ("optimistic", "conservative", "nsbh"):
            mark = " (the decision curve)" if curve == args.curve else ""
            print(f"Split halves, chosen by E {curve}{mark}:\n")
            print("\n".join(split_rows(table, maps, f"expected_{curve}")) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
