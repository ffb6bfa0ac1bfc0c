#!/usr/bin/env python3
"""Rebuild the release's tables (issue 55) from a population ``results.csv`` alone.

Reads one row per (event, row) in the population layout
(``mushrooms.evaluation.study.population_rows.POPULATION_COLUMNS``: the rows ``service``, ``service-grg``,
``greedy``, ``gwemopt-o4``, ``gwemopt-skyportal``, ``gwemopt-repaired``) and writes the Markdown of
``mushrooms.evaluation.study.release_tables.release_tables``: per row the mean and median of planned coverage
(pair rule), executed coverage through the queue set and as submitted today, detection efficiencies and open-shutter
hours, each with a bootstrap 95 % interval; per-event paired differences against the service; the events each row
executes nothing on; the same by class, distance and area. An event without a row of every name of ``--rows``
(default: the six) is listed in the header and left out (a partial run); rows from more than one commit put a
warning at the top.

With ``--curves`` (``study/executed_curves.jsonl.gz``) the matched-time section too: our rows at gwemopt's
open-shutter time, per event. With ``--matched-budget ROWS.jsonl.gz --records RESULTS.jsonl.gz`` the section of the
rows planned under gwemopt-o4's budget (``population_o4_matched_budget.py``), appended at the end.

    .venv/bin/python benchmarks/science/release_tables.py CSV [-o TABLES.md] [--draws 2000] [--seed 0] [--rows A,B]
        [--curves CURVES.jsonl.gz] [--matched-budget ROWS.jsonl.gz --records RESULTS.jsonl.gz]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mushrooms.evaluation.study.matched_tables import read_curves
from mushrooms.evaluation.study.population_rows import read_population_csv
from mushrooms.evaluation.study.release_tables import RELEASE_ROWS, release_tables


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", type=Path)
    ap.add_argument("-o", "--out", type=Path, help="write here (default: stdout)")
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--curves", type=Path, help="our rows' executed curves (study/executed_curves.jsonl.gz): "
                    "adds the matched-time section")
    ap.add_argument("--rows", default=",".join(RELEASE_ROWS),
                    help="row names every tabulated event must have (default %(default)s; '' : those in the CSV)")
    ap.add_argument("--matched-budget", type=Path, nargs="+", help="rows planned under gwemopt-o4's budget "
                    "(matched_budget/service_capped.jsonl.gz): adds their section; needs --records")
    ap.add_argument("--records", type=Path, help="the study's records (study/results.jsonl.gz)")
    args = ap.parse_args()
    if args.matched_budget and not args.records:
        print("--matched-budget needs --records", file=sys.stderr)
        return 2
    if not args.csv.is_file():
        print(f"{args.csv}: no such file", file=sys.stderr)
        return 2
    expected = tuple(r for r in args.rows.split(",") if r)
    curves, failed = read_curves(args.curves) if args.curves else (None, ())
    text = release_tables(read_population_csv(args.csv), draws=args.draws, seed=args.seed, expected=expected,
                          curves=curves, failed=failed)
    if args.matched_budget:
        from mushrooms.evaluation.study.matched_budget import section

        text += "\n" + "\n".join(section(args.records, args.matched_budget, args.draws, args.seed)) + "\n"
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
