"""The split of exact_split.py --refined, after: bound slack with V on the outer refined windows (V7).

Usage::

    python benchmarks/quality/outer_window_split.py SPLIT.csv [-o after.csv]

Reads the rows ``exact_split.py --refined -o SPLIT.csv`` wrote, rebuilds each
reduced instance, computes min(U4, V) on the outer windows
(:func:`mushrooms.evaluation.true_windows.refined_windows`, the same 2 s
solver budget) and prints per instance and on average: the grid optimum,
the outer optimum, V today, V on outer windows, and the bound slack
(bound - grid optimum) before and after, over the instances whose grid
exact model was proven optimal.  Not a test: nothing asserts.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))  # benchmarks/common: the shared helpers
from csv_rows import write_rows  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from exact_split import shared_root  # noqa: E402


def outer_bound(path: Path, k: int, limit: float) -> tuple[float, float]:
    from astropy.time import Time

    import mushrooms.scheduler_core.schedulers.bounds.coverage_bound as bound
    import mushrooms.scheduler_core.schedulers.bounds.interval_bound as interval
    from mushrooms.evaluation.reduced import reduced_problem
    from mushrooms.evaluation.true_windows import refined_windows
    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap

    cfg = PlanningConfig(objective="coverage", threads=1, min_gain=0.0, min_coverage=0.0)
    sm = read_skymap(path, nside=cfg.nside)
    problem = reduced_problem(prepare_problem(sm, cfg, Time(sm.event_time, scale="utc")), k)
    t = time.perf_counter()
    outer = refined_windows(problem, "outer")
    saved = bound.widened_windows
    try:  # every U and V step reads the widened windows through this one function
        bound.widened_windows = interval.widened_windows = lambda p: outer
        value = interval.interval_upper_bound(problem, time_limit_s=limit).value
    finally:
        bound.widened_windows = interval.widened_windows = saved
    return value, time.perf_counter() - t


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("split", type=Path)
    ap.add_argument("--limit", type=float, default=2.0)
    ap.add_argument("-o", "--output", type=Path)
    args = ap.parse_args(argv)
    rows = []
    with args.split.open() as fh:
        src = list(csv.DictReader(fh))
    print(f"{'map':44s} {'k':>3s} {'grid':>7s} {'outer':>7s} {'before':>7s} {'after':>7s} "
          f"{'slack0':>7s} {'slack1':>7s} {'t':>5s}")
    for r in src:
        value, t = outer_bound(shared_root() / r["map"], int(r["k"]), args.limit)
        before = float(r["published_bound"])
        after = min(before, value)  # both are bounds (V5, V7)
        opt = float(r["optimum"])
        row = {"map": r["map"], "k": int(r["k"]), "status": r["status"], "optimum": opt,
               "optimum_outer": float(r["optimum_outer"]), "status_outer": r["status_outer"],
               "bound_before": before, "bound_outer_v": value, "bound_after": after,
               "slack_before": before - opt, "slack_after": after - opt, "t_outer": round(t, 2)}
        rows.append(row)
        print(f"{r['map'][-44:]:44s} {row['k']:3d} {opt:7.4f} {row['optimum_outer']:7.4f} {before:7.4f} {after:7.4f} "
              f"{row['slack_before']:7.4f} {row['slack_after']:7.4f} {t:5.2f}", flush=True)
        if args.output:
            write_rows(args.output, rows)
    for name, sel in (("proven optimal (grid)", [r for r in rows if r["status"] == "optimal"]), ("all", rows)):
        if sel:
            print(f"MEAN over {len(sel)} {name}: optimum {statistics.mean(r['optimum'] for r in sel):.4f}, "
                  f"bound before {statistics.mean(r['bound_before'] for r in sel):.4f} -> after "
                  f"{statistics.mean(r['bound_after'] for r in sel):.4f}; bound slack "
                  f"{statistics.mean(r['slack_before'] for r in sel):.4f} -> {statistics.mean(r['slack_after'] for r in sel):.4f}; "
                  f"optimum/bound {statistics.mean(r['optimum'] / r['bound_before'] for r in sel if r['bound_before'] > 0):.3f}"
                  f" -> {statistics.mean(r['optimum'] / r['bound_after'] for r in sel if r['bound_after'] > 0):.3f}")
    ok = [r for r in rows if r["status_outer"] == "optimal"]
    print(f"after >= outer optimum on {sum(r['bound_after'] >= r['optimum_outer'] - 1e-9 for r in ok)}/{len(ok)} "
          f"(outer proven); time median {statistics.median(r['t_outer'] for r in rows):.2f} s, "
          f"max {max(r['t_outer'] for r in rows):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
