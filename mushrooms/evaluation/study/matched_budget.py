"""The row planned under gwemopt-o4's budget (issue 55): its table against gwemopt-o4, from two files.

``ROWS`` (``population_o4_matched_budget.py``'s output: per event the cap, the capped plan's cells) and the study's
records (``study/results.jsonl.gz``, gwemopt-o4's cells): per capped row the per-event paired difference capped
row − gwemopt-o4 of the executed coverage (queue set) and of the pair-rule planned coverage, mean [95 %] / median
[95 %] (better/worse/tied beyond :data:`~.release_stats.TIE`), and the open shutter each spent.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

from .release_stats import TIE, cell, summary

__all__ = ["table", "section", "NOTE"]


def tally(d: list[float]) -> str:
    """``(better/worse/tied of n)``."""
    return f" ({sum(x > TIE for x in d)}/{sum(x < -TIE for x in d)}/{sum(abs(x) <= TIE for x in d)} of {len(d)})"


def num(x) -> float:
    """A cell as a number (empty: 0)."""
    return float(x) if x not in (None, "") else 0.0


def table(records: list[dict], capped: list[dict], draws: int = 2000, seed: int = 0) -> list[str]:
    """Markdown lines of the deciding table."""
    by = {(r["map"], r["solver"]): r["row"] for r in records}
    lines = ["| capped row − gwemopt-o4 | events | executed via queue set | planned (pair rule) | "
             "open shutter executed (h): capped row / gwemopt-o4 | open shutter planned (h): capped row / budget | "
             "uncapped row − gwemopt-o4, executed, same events |",
             "|---|---|---|---|---|---|---|"]
    for row in sorted({c["row"] for c in capped}):
        mine = {c["map"]: c for c in capped if c["row"] == row}
        ev = sorted(m for m in mine if (m, "gwemopt-o4") in by)
        base = row.removesuffix("-capped")
        ex = [num(mine[e]["cells"]["coverage_as_executed"]) - num(by[e, "gwemopt-o4"]["coverage_as_executed"]) for e in ev]
        pl = [num(mine[e]["cells"]["coverage_pairs"]) - num(by[e, "gwemopt-o4"]["coverage_pairs"]) for e in ev]
        full = [num(by[e, base]["coverage_as_executed"]) - num(by[e, "gwemopt-o4"]["coverage_as_executed"])
                for e in ev if (e, base) in by]
        os_mine = summary([num(mine[e]["cells"]["open_shutter_executed_s"]) / 3600 for e in ev], draws, seed)
        os_base = summary([num(by[e, "gwemopt-o4"]["open_shutter_executed_s"]) / 3600 for e in ev], draws, seed)
        os_plan = summary([num(mine[e]["cells"]["open_shutter_s"]) / 3600 for e in ev], draws, seed)
        os_cap = summary([num(mine[e]["cap_s"]) / 3600 for e in ev], draws, seed)
        lines.append(f"| {row} − gwemopt-o4 | {len(ev)} | {cell(summary(ex, draws, seed), sign=True)}{tally(ex)} | "
                     f"{cell(summary(pl, draws, seed), sign=True)}{tally(pl)} | "
                     f"{os_mine['mean']:.2f} / {os_base['mean']:.2f} | {os_plan['mean']:.2f} / {os_cap['mean']:.2f} | "
                     f"{cell(summary(full, draws, seed), sign=True)}{tally(full)} |")
    return lines


#: What the section is, said above its table.
NOTE = (
    "The row the matched-time stand-ins above could not give: the service (and service-grg, if run) PLANNED under gwemopt-o4's budget, "
    "`[scheduler] max_open_shutter_s` = gwemopt-o4's open-shutter seconds executed (queue set, the study's "
    "executor) on each event; the planner then chooses its fields for that budget (greedy stops before the field "
    "whose visits would pass it, the slot MILPs and the detection stage carry it as S4, docs/design/milp.md). "
    "Planned by the CURRENT code ({commits}), not the frozen af0ff7d: the cap did not exist there; gwemopt-o4's "
    "values are the frozen records'. Same study configuration, deterministic budget, same executor and pair rule "
    "(the light scorer of population_o4_replan.py: no detection columns). An event where gwemopt-o4 executes "
    "nothing gets no plan (0, a tie). PARTIAL: events of the 50-event snapshot planned, per row: {n} (the release needs >= 250); "
    "quote none of these numbers as the release's. `benchmarks/science/population_o4_matched_budget.py`, "
    "`results/science/population_o4/matched_budget/`.")


def section(records_path: Path, rows_paths: Path | list[Path], draws: int = 2000, seed: int = 0) -> list[str]:
    """The Markdown section (heading, note, table, cap check) from the records and one or more row files."""
    records = [json.loads(line) for line in gzip.open(records_path, "rt")]
    paths = [rows_paths] if isinstance(rows_paths, (str, Path)) else list(rows_paths)
    capped = [json.loads(line) for path in paths for line in gzip.open(path, "rt")]
    over = [c for c in capped if c["planned"] and num(c["cells"]["open_shutter_s"]) > c["cap_s"] + 1e-6]
    commits = sorted({c.get("commit") or "" for c in capped if c["planned"]} - {""})
    n = ", ".join(f"{len({c['map'] for c in capped if c['row'] == r})} ({r})" for r in sorted({c["row"] for c in capped}))
    return (["## Under gwemopt-o4's budget, planned (PARTIAL)", "",
             NOTE.format(commits=", ".join(f"`{c[:12]}`" for c in commits) or "-", n=n), ""]
            + table(records, capped, draws, seed)
            + ["", f"Plans over their cap: {len(over)} of {sum(c['planned'] for c in capped)} planned "
                   f"({sum(not c['planned'] for c in capped)} (event, row) with no gwemopt-o4 open shutter: no plan, "
                   "0). Intervals: bootstrap over events, {draws} resamples, seed {seed}; better/worse/tied beyond "
                   f"{TIE:g}.".replace("{draws}", str(draws)).replace("{seed}", str(seed))])
