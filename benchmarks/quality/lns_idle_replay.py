"""What a shorter LNS idle stop would have kept: read off the trajectories of ``lns_stage.py --lns-idle``.

Usage::

    python benchmarks/quality/lns_idle_replay.py RESULTS.txt [--idle 1 2 3 5]

``RESULTS.txt`` is the output of ``benchmarks/quality/lns_stage.py --lns-idle S`` with a large ``S`` (the LNS
then runs to the end of its budget): per map the LNS's seed coverage, its gains ``(s, coverage)`` and its
wall time.  The idle stop is checked before each slice, so with a stop of ``X`` seconds a gain is still
found when its slice started at most ``X`` after the previous gain (or the LNS's start), and the LNS ends
with the first slice started later than that.  A slice's start is not recorded: the replay takes it as
``max(previous gain, gain - L)`` with ``L`` the slice limit (``--slice-limit``, default 2.07 s: the gains
on the shared maps come at multiples of ~2.07 s, slices that used their whole 2 s limit), and the time
the LNS takes as ``min(run's time, previous gain + X + L)``.  Printed per ``X``: the mean and the largest
coverage lost against the run to the budget (absolute), the maps that lose more than 1e-3, and the median
and total LNS time.
Not a test: nothing here asserts.
"""

from __future__ import annotations

import argparse
import ast
import re
import statistics
import sys


def parse(path: str) -> list[dict]:
    """One dict per map line: ``map``, ``seed`` (coverage), ``gains`` [(s, coverage)], ``lns_s``."""
    rows = []
    for line in open(path):
        m = re.search(r"^\S+ (\S+) .*lns_seed=(\S+) lns_s=(\S+) gains=(\[.*?\]) times=", line)
        if m:
            rows.append({"map": m.group(1), "seed": float(m.group(2)), "lns_s": float(m.group(3)),
                         "gains": ast.literal_eval(m.group(4))})
    return rows


def replay(row: dict, idle_s: float, slice_limit_s: float) -> tuple[float, float]:
    """(coverage kept, LNS seconds) had the LNS stopped after ``idle_s`` s without a gain."""
    cov, last = row["seed"], 0.0
    for t, c in row["gains"]:
        if max(last, t - slice_limit_s) - last > idle_s:
            break
        cov, last = c, t
    return cov, min(row["lns_s"], last + idle_s + slice_limit_s)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results")
    ap.add_argument("--idle", type=float, nargs="+", default=[1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0])
    ap.add_argument("--slice-limit", type=float, default=2.07, help="wall time (s) of a slice that uses its limit")
    args = ap.parse_args(argv)
    rows = [r for r in parse(args.results) if r["seed"] == r["seed"]]  # no LNS run: nan seed
    full = {r["map"]: (r["gains"][-1][1] if r["gains"] else r["seed"]) for r in rows}
    print(f"{len(rows)} maps with an LNS run; {sum(bool(r['gains']) for r in rows)} with a gain; "
          f"median LNS time run to its budget {statistics.median(r['lns_s'] for r in rows):.2f} s")
    print(f"{'idle s':>6} {'mean lost':>10} {'max lost':>9} {'maps >1e-3':>10} {'median lns s':>12} {'total lns s':>11}")
    for x in args.idle:
        kept = {r["map"]: replay(r, x, args.slice_limit) for r in rows}
        lost = {m: full[m] - kept[m][0] for m in kept}
        worst = sorted((m for m in lost if lost[m] > 1e-3), key=lambda m: -lost[m])
        print(f"{x:6.1f} {statistics.mean(lost.values()):10.5f} {max(lost.values()):9.5f} {len(worst):10d} "
              f"{statistics.median(k[1] for k in kept.values()):12.2f} {sum(k[1] for k in kept.values()):11.1f}"
              + ("  " + ", ".join(f"{m} {lost[m]:.4f}" for m in worst) if worst else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
