#!/usr/bin/env python3
"""The deciding row's table (issue 55): the service planned under gwemopt-o4's open-shutter time, against gwemopt-o4.

Prints the Markdown section of :func:`mushrooms.evaluation.study.matched_budget.section` (the same that
``release_tables.py --matched-budget`` appends to ``release_tables.md``).

    /work/main/.venv/bin/python benchmarks/science/population_o4_matched_budget_table.py \\
        --records benchmarks/results/science/population_o4/study/results.jsonl.gz --rows ROWS.jsonl.gz
"""

from __future__ import annotations

import argparse
from pathlib import Path

from mushrooms.evaluation.study.matched_budget import section


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=Path, required=True)
    ap.add_argument("--rows", type=Path, nargs="+", required=True)
    args = ap.parse_args()
    print("\n".join(section(args.records, args.rows)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
