"""The published bound min(U4, V) with the windows' ends refined (outer, evaluation/true_windows.py) on every shared map.

Usage::

    python benchmarks/quality/outer_window_bound.py [-o table.csv] [--limit 2]

U1-U4 and V1-V4 widen every window by one grid step; the outer refined
windows (``docs/design/milp.md`` V7) also contain every exposure of a
checker-accepted plan and are narrower, so the same bounds computed on them
are valid and tighter.  Per map (default config, coverage objective,
``threads = 1``): greedy's coverage, the published bound today, the bound
on outer windows, the time of each (the refinement included).  An
experiment: the scheduler does not use it.  Not a test: nothing asserts.
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


def measure(path: Path, limit: float) -> dict:
    from astropy.time import Time

    import mushrooms.scheduler_core.schedulers.bounds.coverage_bound as bound
    import mushrooms.scheduler_core.schedulers.bounds.interval_bound as interval
    from mushrooms.evaluation.true_windows import refined_windows
    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import run_scheduler

    cfg = PlanningConfig(objective="coverage", threads=1)
    sm = read_skymap(path, nside=cfg.nside)
    problem = prepare_problem(sm, cfg, Time(sm.event_time, scale="utc"))
    greedy = run_scheduler(problem, "greedy")
    cov = problem.footprints.coverage({o.field_id for o in greedy.observations}, problem.prob)
    t = time.perf_counter()
    today = interval.interval_upper_bound(problem, time_limit_s=limit)
    t_today = time.perf_counter() - t
    t = time.perf_counter()
    outer = refined_windows(problem, "outer")
    t_refine = time.perf_counter() - t
    saved = bound.widened_windows
    try:  # every U and V step reads the widened windows through this one function
        bound.widened_windows = interval.widened_windows = lambda p: outer
        refined = interval.interval_upper_bound(problem, time_limit_s=limit)  # the same solver budget
    finally:
        bound.widened_windows = interval.widened_windows = saved
    t_outer = time.perf_counter() - t
    return {"map": str(path.relative_to(shared_root())), "greedy": cov, "bound": today.value, "method": today.method,
            "bound_outer": refined.value, "method_outer": refined.method, "t_bound": round(t_today, 2),
            "t_outer": round(t_outer, 2), "t_refine": round(t_refine, 2)}


def main(argv: list[str] | None = None) -> int:
    from mushrooms.evaluation.bench import find_skymaps

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=float, default=2.0, help="budget (s) of each bound, refinement included")
    ap.add_argument("-o", "--output", type=Path)
    args = ap.parse_args(argv)
    rows = []
    print(f"{'map':44s} {'greedy':>7s} {'bound':>7s} {'outer':>7s} {'g/b':>6s} {'g/outer':>7s} {'t':>5s} {'t_out':>5s}")
    for path in find_skymaps(shared_root()):
        try:
            r = measure(path, args.limit)
        except Exception as exc:  # a benchmark reports, it does not stop
            print(f"{str(path)[-44:]:44s} ERROR {type(exc).__name__}: {exc}", flush=True)
            continue
        rows.append(r)
        print(f"{r['map'][-44:]:44s} {r['greedy']:7.4f} {r['bound']:7.4f} {r['bound_outer']:7.4f} "
              f"{r['greedy'] / max(r['bound'], 1e-12):6.3f} {r['greedy'] / max(r['bound_outer'], 1e-12):7.3f} {r['t_bound']:5.2f} {r['t_outer']:5.2f}",
              flush=True)
        if args.output:
            write_rows(args.output, rows)
    ok = [r for r in rows if r["bound"] > 0 and r["bound_outer"] > 0]
    for key, name in (("bound", "today"), ("bound_outer", "outer windows")):
        ratios = [r["greedy"] / r[key] for r in ok]
        times = [r["t_bound" if key == "bound" else "t_outer"] for r in ok]
        print(f"{name}: mean bound {statistics.mean(r[key] for r in ok):.4f}, mean greedy/bound {statistics.mean(ratios):.3f}, "
              f"median {statistics.median(ratios):.3f}, maps below 0.8: {sum(x < 0.8 for x in ratios)}/{len(ok)}, "
              f"time median {statistics.median(times):.2f} s, max {max(times):.2f} s")
    print(f"outer <= today on {sum(r['bound_outer'] <= r['bound'] + 1e-9 for r in ok)}/{len(ok)}; "
          f"greedy <= outer on {sum(r['greedy'] <= r['bound_outer'] + 1e-9 for r in ok)}/{len(ok)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
