"""Would a slot plan made at the cadence plus a margin be the hybrid's choice as executed (Q15)?

The executor opens a filter pass the cadence plus 120 s (Q11) after its partners' executed first visits,
so plans packed at the exact cadence lose pairs as executed, and the hybrid (Q15) often keeps greedy's
plan.  Per map: the shipped coverage stage (the hybrid, ``time_limit_s - detection_time_limit_s``) once,
each candidate's planned and executed coverage; then, per margin, the slot stage started from greedy on
the problem with ``cadence_s + margin`` (its plans keep every pair that much further apart), scored on the
real problem, planned and executed, with its wall time.

    python benchmarks/execution/cadence_margin_candidate.py [--margins 120] [--out FILE] [MAP ...]

Every *.fits / *.fits.gz under ../shared/data/skymaps/{public,simulated} unless maps are given.  The
summary goes to FILE.summary.txt: executed and planned coverage of the hybrid's choice with and without
each margin's plan as one more candidate, the maps where it would be chosen.  Not a test: nothing asserts.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks" / "common"))

from paired_maps import map_key, paired_rows, shared_maps, write_summary  # noqa: E402


def run_map(path: Path, margins: list[float]) -> dict:
    """One map: the hybrid's candidates, then the slot stage at each widened cadence."""
    from mushrooms.scheduler_core.planner import coverage_stage_problem, run_scheduler
    from mushrooms.scheduler_core.prepare import prepare_problem
    from mushrooms.scheduler_core.schedulers.gain import published_coverage
    from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
    from mushrooms.scheduler_core.schedulers.slots.schedule import slot_schedule
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverage_as_executed
    from mushrooms.tool.config import load_config

    cfg = load_config(ROOT / "config.toml").scheduler
    sm = read_skymap(path, nside=cfg.nside)
    problem = coverage_stage_problem(prepare_problem(sm, cfg, sm.event_time))
    t0 = time.perf_counter()
    hyb = run_scheduler(problem, cfg.solver)
    row: dict = {"map": map_key(path), "hybrid_s": round(time.perf_counter() - t0, 3),
                 "choice": hyb.portfolio_choice,
                 "planned": {e.name: e.coverage for e in hyb.portfolio},
                 "executed": dict(hyb.details.get("coverage_as_executed", {}))}
    # candidates Q15 stopped before: their executed coverage too
    for e in hyb.portfolio:
        if e.name not in row["executed"]:
            row["executed"][e.name] = None
    limit = problem.config.time_limit_s
    for margin in margins:
        wide = dataclasses.replace(problem, config=dataclasses.replace(
            problem.config, cadence_s=problem.config.cadence_s + margin))
        t1 = time.perf_counter()
        start = greedy_schedule(wide)
        res = slot_schedule(wide, None, start=start, time_limit_s=limit)
        if not res.observations:
            res = start
        wall = time.perf_counter() - t1
        row[f"margin={margin:g}"] = {"wall_s": round(wall, 3), "planned": published_coverage(problem, res),
                                     "executed": keyed_coverage_as_executed(problem, res)[1], "status": res.status}
    row["load"] = os.getloadavg()[0]
    return row


def summary(rows: list[dict], margins: list[float]) -> str:
    """Executed and planned coverage of the choice with and without the margin candidate."""
    def best(row: dict, extra: str | None) -> tuple[float, float]:
        cands = {n: (x, row["planned"][n]) for n, x in row["executed"].items() if x is not None}
        if extra is not None:
            cands[extra] = (row[extra]["executed"], row[extra]["planned"])
        name = max(cands, key=lambda n: cands[n])
        return cands[name]

    lines = [f"maps: {len(rows)}; load (1-min) median {statistics.median(r['load'] for r in rows):.1f}",
             f"hybrid as shipped: executed mean {statistics.fmean(best(r, None)[0] for r in rows):.4f}, "
             f"planned mean {statistics.fmean(best(r, None)[1] for r in rows):.4f}, "
             f"greedy kept on {sum(r['choice'] == 'greedy' for r in rows)}; "
             f"planned / greedy x{sum(best(r, None)[1] for r in rows) / sum(r['planned']['greedy'] for r in rows):.4f}"]
    for m in margins:
        key = f"margin={m:g}"
        with_m = [best(r, key) for r in rows]
        base = [best(r, None) for r in rows]
        de = [a[0] - b[0] for a, b in zip(with_m, base)]
        dp = [a[1] - b[1] for a, b in zip(with_m, base)]
        se = statistics.stdev(de) / len(de) ** 0.5 if len(de) > 1 else float("nan")
        chosen = [r["map"] for r, a, b in zip(rows, with_m, base) if a[0] > b[0] + 1e-9]
        lines.append(f"+ slots at cadence + {m:g} s as a candidate: executed {statistics.fmean(de):+.4f} ± {se:.4f} "
                     f"(chosen on {len(chosen)}), planned {statistics.fmean(dp):+.4f}; planned / greedy "
                     f"x{sum(a[1] for a in with_m) / sum(r['planned']['greedy'] for r in rows):.4f}; its wall p50 "
                     f"{statistics.median(r[key]['wall_s'] for r in rows):.2f} s; chosen on {chosen}")
        alone = [r[key]["executed"] - best(r, None)[0] for r in rows]
        lines.append(f"  alone instead of the hybrid: executed {statistics.fmean(alone):+.4f}, "
                     f"better on {sum(x > 1e-4 for x in alone)}, worse on {sum(x < -1e-4 for x in alone)}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*", type=Path)
    ap.add_argument("--margins", nargs="+", type=float, default=[120.0])
    ap.add_argument("--out", type=Path,
                    default=ROOT / "benchmarks" / "results" / "speed" / "runs" / "cadence_margin_candidate.jsonl")
    args = ap.parse_args(argv)

    def describe(row: dict) -> str:
        ex = {n: x for n, x in row["executed"].items() if x is not None}
        return (f"choice {row['choice']} exec {max(ex.values(), default=0):.4f} "
                + " ".join(f"m{m:g} exec {row[f'margin={m:g}']['executed']:.4f}" for m in args.margins))

    rows = paired_rows(args.out, shared_maps(args.maps), lambda p, i: run_map(p, args.margins), describe)
    write_summary(args.out, f"the hybrid's candidates and slots at cadence + {args.margins} s",
                  summary(rows, args.margins))
    return 0


if __name__ == "__main__":
    sys.exit(main())
