"""The before/after table of ``switch_rules.py``'s rows (issue 52, findings 12-13).

    python benchmarks/execution/summarise.py ROWS.jsonl [> TABLE.md]

Per map and solver: the plan's own ``coverage_as_executed`` (main's model before, this tree's after), and
the coverage this tree's executor (ztf_sim's rules) gives its queue set under first-wins / last-wins, on
time; for the before plan re-exported here too (the export's effect alone).  Then, per late start, the mean
over rows and how many rows differ between the two rules.  For g-r-g rows the coverage of the fields whose
whole sequence is executed (Q21) and the third visits lost / too soon.
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path


def _pair(d: dict, late: int, suffix: str = "") -> str:
    if not d:
        return "–"
    return f"{d[f'first_{late}{suffix}']:.3f} / {d[f'last_{late}{suffix}']:.3f}"


def table(rows: list[dict]) -> str:
    grg = any(r.get("grg") for r in rows)
    head = ["map", "solver", "planned", "before: own figure", "before: first / last",
            "same plan re-exported: first / last", "after: own figure", "after: first / last"]
    if grg:
        head += ["before whole: first / last", "after whole: first / last", "before 3rd lost / too soon (last)",
                 "after 3rd lost / too soon (last)"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if r.get("empty"):
            continue
        cells = [r["map"], r["solver"], f"{r['planned_before']:.3f}" + ("" if r["same_plan"] else
                                                                          f" → {r['planned_after']:.3f}"),
                 f"{r['before_metric']:.3f}", _pair(r["before"], 0), _pair(r["before_reexported"], 0),
                 f"{r['after_metric']:.3f}", _pair(r["after"], 0)]
        if grg:
            b, a = r["before"]["last_0_thirds"], r["after"]["last_0_thirds"]
            cells += [_pair(r["before"], 0, "_whole"), _pair(r["after"], 0, "_whole"),
                      f"{b['lost']} / {b['too_soon']} of {b['fields']}", f"{a['lost']} / {a['too_soon']} of {a['fields']}"]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out)


def late_summary(rows: list[dict]) -> str:
    rows = [r for r in rows if not r.get("empty") and r.get("after")]
    lines = ["", "| late (min) | arm | mean first-wins | mean last-wins | rows where they differ (> 0.0005) |",
             "|---|---|---|---|---|"]
    for late in (0, 15, 30, 60):
        for arm in ("before", "before_reexported", "after"):
            first = [r[arm][f"first_{late}"] for r in rows]
            last = [r[arm][f"last_{late}"] for r in rows]
            differ = sum(abs(a - b) > 5e-4 for a, b in zip(first, last))
            lines.append(f"| {late} | {arm} | {statistics.fmean(first):.4f} | {statistics.fmean(last):.4f} | "
                         f"{differ} of {len(rows)} |")
    loads = [r["load"] for r in rows]
    lines.append(f"\n{len(rows)} rows; load (1-min) at each row's end: median {statistics.median(loads):.1f}, "
                 f"max {max(loads):.1f}; export s (median) before {statistics.median(r['export_s_before'] for r in rows):.2f}, "
                 f"after {statistics.median(r['export_s_after'] for r in rows):.2f}")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    rows = [json.loads(line) for line in Path(argv[0]).read_text().splitlines() if line.strip()]
    print(table(rows))
    print(late_summary(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
