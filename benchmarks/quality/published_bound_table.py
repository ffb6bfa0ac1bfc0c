"""The published bound min(U4, V) on every shared sky map: coverage / bound, and where the hybrid stops early.

Usage::

    python benchmarks/quality/published_bound_table.py [--hybrid MAP_NAME ...] [--plan-limit 10] [--k K]
                                               [-o table.csv] [MAP_DIR ...]

Per map (default: every map under ``shared/data/skymaps``), with the default
configuration but the coverage objective and ``threads = 1``: greedy's
published coverage (after the least-gain rule), the online bound U4, the
published bound (:func:`~mushrooms.scheduler_core.schedulers.bounds.certified_bound.certified_upper_bound`,
``bound_time_limit_s`` = 2 s) and which one it is, and whether greedy's plan
reaches it (:func:`~mushrooms.scheduler_core.schedulers.portfolio.portfolio.reaches_bound`:
the hybrid then skips its MILP stages).  For the maps named by ``--hybrid``
(a substring of the map's path) the default hybrid is run too
(``time_limit_s = --plan-limit``): its coverage, the stages it ran and
skipped.  ``--k``: each map reduced to its top ``k`` pairable fields
(:func:`mushrooms.evaluation.reduced.reduced_problem`, as in
``exact_split.py``), where greedy is often optimal.  Then the counts and
the mean ratios.  Wall times are printed
for orientation only.  Not a test: nothing here asserts.
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


def measure(path: Path, hybrid: bool, plan_limit: float, k: int | None = None) -> dict:
    from astropy.time import Time

    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import run_scheduler
    from mushrooms.scheduler_core.schedulers.bounds.coverage_bound import coverage_upper_bound
    from mushrooms.scheduler_core.schedulers.bounds.certified_bound import certified_upper_bound
    from mushrooms.scheduler_core.schedulers.gain import published_coverage
    from mushrooms.scheduler_core.schedulers.portfolio.portfolio import reaches_bound

    cfg = PlanningConfig(objective="coverage", threads=1, milp_backend="highs", time_limit_s=plan_limit)
    sm = read_skymap(path, nside=cfg.nside)
    problem = prepare_problem(sm, cfg, Time(sm.event_time, scale="utc"))
    if k is not None:
        from mushrooms.evaluation.reduced import reduced_problem

        problem = reduced_problem(problem, k)
    greedy = published_coverage(problem, run_scheduler(problem, "greedy"))
    u4 = coverage_upper_bound(problem)
    bound = certified_upper_bound(problem)
    row = {"map": str(path.relative_to(shared_root())), "greedy": greedy, "U4": u4.value,
           "bound": bound.value, "method": bound.method, "status": bound.status,
           "bound_s": round(bound.runtime_s, 3), "greedy_reaches": reaches_bound(greedy, bound)}
    if hybrid:
        t = time.perf_counter()
        res = run_scheduler(problem, "hybrid")
        row.update(hybrid=published_coverage(problem, res), hybrid_s=round(time.perf_counter() - t, 2),
                   hybrid_ran="+".join(e.name for e in res.portfolio),
                   hybrid_skipped="+".join(res.details.get("skipped_at_bound", [])),
                   hybrid_bound=res.upper_bound.value, hybrid_method=res.upper_bound.method)
    return row


def main(argv: list[str] | None = None) -> int:
    from mushrooms.evaluation.bench import find_skymaps

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="*", type=Path)
    ap.add_argument("--hybrid", nargs="*", default=[], help="substrings of the maps to run the hybrid on")
    ap.add_argument("--plan-limit", type=float, default=10.0, help="the hybrid's time_limit_s (s)")
    ap.add_argument("--k", type=int, default=None, help="reduce each map to its top k pairable fields")
    ap.add_argument("-o", "--output", type=Path)
    args = ap.parse_args(argv)
    dirs = args.dirs or [shared_root()]
    maps = [p for d in dirs for p in find_skymaps(d)]
    rows = []
    t0 = time.perf_counter()
    for p in maps:
        want = any(s in str(p) for s in args.hybrid)
        try:
            row = measure(p, want, args.plan_limit, args.k)
        except Exception as exc:  # a map the planner refuses: reported, not counted
            print(f"{p}: {type(exc).__name__}: {exc}", flush=True)
            continue
        rows.append(row)
        extra = (f"  hybrid {row['hybrid']:.4f} ran {row['hybrid_ran']} skipped {row['hybrid_skipped'] or '-'}"
                 f" ({row['hybrid_s']:.1f} s)") if want else ""
        print(f"{row['map']:<50} greedy {row['greedy']:.4f}  U4 {row['U4']:.4f}  bound {row['bound']:.4f} "
              f"{row['method']:<8} {row['bound_s']:5.2f} s  {'REACHED' if row['greedy_reaches'] else ''}{extra}",
              flush=True)
    ok = [r for r in rows if r["bound"] > 0]
    print(f"maps {len(rows)} (bound > 0: {len(ok)}); bound is V on {sum(r['method'] == 'interval' for r in ok)}; "
          f"greedy reaches the bound (the hybrid stops after greedy) on {sum(r['greedy_reaches'] for r in ok)}")
    print(f"mean greedy / U4 {statistics.fmean(r['greedy'] / r['U4'] for r in ok):.4f}, greedy / bound "
          f"{statistics.fmean(r['greedy'] / r['bound'] for r in ok):.4f}; median greedy / bound "
          f"{statistics.median(r['greedy'] / r['bound'] for r in ok):.4f}; mean U4 {statistics.fmean(r['U4'] for r in ok):.4f},"
          f" mean bound {statistics.fmean(r['bound'] for r in ok):.4f}; median bound time "
          f"{statistics.median(r['bound_s'] for r in ok):.2f} s")
    hy = [r for r in ok if "hybrid" in r]
    if hy:
        print(f"hybrid on {len(hy)} maps: mean hybrid / U4 {statistics.fmean(r['hybrid'] / r['U4'] for r in hy):.4f}, "
              f"hybrid / bound {statistics.fmean(r['hybrid'] / r['bound'] for r in hy):.4f}; stopped early on "
              f"{sum(bool(r['hybrid_skipped']) for r in hy)}")
    print(f"wall {time.perf_counter() - t0:.0f} s")
    if args.output:
        write_rows(args.output, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
