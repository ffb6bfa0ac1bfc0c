"""Per-map table of the schedulers from a ``mushrooms bench`` CSV.

    python benchmarks/quality/scheduler_table.py results.csv [--solvers greedy,slots,blocks,hybrid]

Columns: coverage of each solver (checker), the certified upper bound, the
default (hybrid) coverage divided by the bound, and the wall time of each
solver's solve (s).  Then means and medians, the hybrid/greedy ratio of the
means, and the maps where the hybrid covers less than greedy or fails the
checker.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from mushrooms.evaluation.bench import read_csv


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", type=Path)
    ap.add_argument("--solvers", default="greedy,slots,blocks,hybrid")
    ap.add_argument("--default", default="hybrid")
    args = ap.parse_args()
    solvers = args.solvers.split(",")
    rows = read_csv(args.csv)
    maps: dict[str, dict[str, dict]] = {}
    for r in rows:
        maps.setdefault(r["skymap"], {})[r["solver"]] = r
    head = (f"{'map':34s}" + "".join(f"{s:>9s}" for s in solvers) + f"{'bound':>9s}{'cov/bnd':>8s}"
            + "".join(f"{'t_' + s[:5]:>8s}" for s in solvers) + "  valid")
    print(head)
    print("-" * len(head))
    cols: dict[str, list[float]] = {k: [] for k in solvers + ["bound", "ratio"] + [f"t_{s}" for s in solvers]}
    worse, invalid = [], []
    for m in sorted(maps):
        sol = maps[m]
        if not all(s in sol and sol[s].get("coverage") is not None for s in solvers):
            print(f"{Path(m).parent.name + '/' + Path(m).name:34s} incomplete")
            continue
        cov = {s: float(sol[s]["coverage"]) for s in solvers}
        bound = float(sol[solvers[0]].get("bound") or 0.0)
        d = cov[args.default]
        ratio = d / bound if bound > 0 else float("nan")
        valid = all(sol[s].get("valid") for s in solvers)
        if d < cov["greedy"] - 1e-9:
            worse.append(m)
        if not sol[args.default].get("valid"):
            invalid.append(m)
        times = {s: float(sol[s].get("solve_s") or 0.0) for s in solvers}
        print(f"{Path(m).parent.name + '/' + Path(m).name:34s}" + "".join(f"{cov[s]:9.4f}" for s in solvers)
              + f"{bound:9.4f}{ratio:8.3f}" + "".join(f"{times[s]:8.1f}" for s in solvers)
              + f"  {'yes' if valid else 'NO'}")
        for s in solvers:
            cols[s].append(cov[s])
            cols[f"t_{s}"].append(times[s])
        cols["bound"].append(bound)
        if bound > 0:
            cols["ratio"].append(ratio)
    for name, fn in (("mean", statistics.mean), ("median", statistics.median)):
        print(f"{name:34s}" + "".join(f"{fn(cols[s]):9.4f}" for s in solvers) + f"{fn(cols['bound']):9.4f}"
              + f"{fn(cols['ratio']):8.3f}" + "".join(f"{fn(cols['t_' + s]):8.1f}" for s in solvers))
    n = len(cols["greedy"])
    g, h = statistics.mean(cols["greedy"]), statistics.mean(cols[args.default])
    rel = [b / a for a, b in zip(cols["greedy"], cols[args.default]) if a > 0]
    print(f"\n{n} maps; mean {args.default} / mean greedy = {h / g:.4f}; median per-map ratio "
          f"{statistics.median(rel):.4f}; {args.default} below greedy on {len(worse)} map(s)"
          f"{': ' + ', '.join(Path(m).name for m in worse) if worse else ''}; "
          f"{args.default} failing the checker on {len(invalid)} map(s)")
    for s in solvers:
        if s == "greedy":
            continue
        w = sum(1 for a, b in zip(cols["greedy"], cols[s]) if b > a + 1e-4)
        lo = sum(1 for a, b in zip(cols["greedy"], cols[s]) if b < a - 1e-4)
        print(f"  {s:8s} vs greedy: better on {w}, worse on {lo}, tied on {n - w - lo} (tie <= 1e-4)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
