"""The interval bound (V1-V4) against the published bound (U4) on every shared sky map.

Usage::

    python benchmarks/quality/interval_bound_table.py [--limits 2,10] [-o table.csv] [MAP_DIR ...]

Per map (default: every map under ``shared/data/skymaps``), with the default
configuration but the coverage objective and ``threads = 1``: the online
bound U4 as every plan publishes it, the interval bound V with each time
limit of ``--limits`` (s), their wall times, and greedy's coverage (a plan
both must exceed).  Then the means and the number of maps where V is below
U4.  Not a test: nothing here asserts.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))  # benchmarks/common: the shared helpers
from csv_rows import write_rows  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from exact_split import shared_root  # noqa: E402


def measure(path: Path, limits: list[float]) -> dict:
    from astropy.time import Time

    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import run_scheduler
    from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
    from mushrooms.scheduler_core.schedulers.bounds.interval_bound import interval_upper_bound

    cfg = PlanningConfig(objective="coverage", threads=1, milp_backend="highs")
    sm = read_skymap(path, nside=cfg.nside)
    problem = prepare_problem(sm, cfg, Time(sm.event_time, scale="utc"))
    greedy = run_scheduler(problem, "greedy")
    row = {"map": str(path.relative_to(shared_root())),
           "greedy": problem.footprints.coverage({o.field_id for o in greedy.observations}, problem.prob)}
    t = time.perf_counter()
    row["U4"] = coverage_upper_bound(problem).value
    row["U4_s"] = round(time.perf_counter() - t, 3)
    for limit in limits:
        v = interval_upper_bound(problem, time_limit_s=limit)
        row[f"V{limit:g}"] = v.value
        row[f"V{limit:g}_status"] = v.status
        row[f"V{limit:g}_s"] = round(v.runtime_s, 3)
    return row


def main(argv: list[str] | None = None) -> int:
    from mushrooms.evaluation.bench import find_skymaps

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", type=Path)
    ap.add_argument("--limits", default="2,10", help="time limits (s) of the interval bound, comma-separated")
    ap.add_argument("-o", "--output", type=Path)
    args = ap.parse_args(argv)
    limits = [float(x) for x in args.limits.split(",")]
    maps = [p for d in (args.dirs or [shared_root()]) for p in find_skymaps(d)]
    rows = []
    for path in maps:
        try:
            r = measure(path, limits)
        except Exception as exc:  # a benchmark reports, it does not stop
            print(f"{path.name}: ERROR {type(exc).__name__}: {exc}", flush=True)
            continue
        rows.append(r)
        print(f"{r['map'][-44:]:44s} greedy {r['greedy']:.4f} U4 {r['U4']:.4f} "
              + " ".join(f"V{x:g} {r[f'V{x:g}']:.4f} ({r[f'V{x:g}_s']:.1f} s, {r[f'V{x:g}_status']})" for x in limits),
              flush=True)
        if args.output:
            write_rows(args.output, rows)
    if rows:
        print(f"{len(rows)} maps: mean greedy {statistics.mean(r['greedy'] for r in rows):.4f}, "
              f"mean U4 {statistics.mean(r['U4'] for r in rows):.4f}")
        for x in limits:
            key = f"V{x:g}"
            print(f"  {key}: mean {statistics.mean(r[key] for r in rows):.4f}, below U4 by > 1e-4 on "
                  f"{sum(r[key] < r['U4'] - 1e-4 for r in rows)} maps, mean greedy/{key} "
                  f"{statistics.mean(r['greedy'] / r[key] for r in rows if r[key] > 0):.3f} (greedy/U4 "
                  f"{statistics.mean(r['greedy'] / r['U4'] for r in rows if r['U4'] > 0):.3f}), "
                  f"median time {statistics.median(r[key + '_s'] for r in rows):.2f} s, "
                  f"greedy <= {key} on {sum(r['greedy'] <= r[key] + 1e-9 for r in rows)}/{len(rows)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
