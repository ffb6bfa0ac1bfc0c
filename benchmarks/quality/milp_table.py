"""The MUSHROOMS MILP on every sky map: model size, solver progress, coverage.

Usage::

    python benchmarks/quality/milp_table.py [--time-limit 30] [--cli-runs N] [-o table.csv] [MAP_DIR_OR_FILE ...]

Per map (default: ``shared/data/skymaps/public`` and ``.../simulated/bns_o3``),
with the default planning configuration and the map's event time as start:
pixels with probability inside the shortlist versus merged cells, the block
model's size (variables / integers / rows / nonzeros), the backend, time to
the first incumbent, time to a 1 % gap (empty: never reached), final gap and
status, retries, and the coverage of the greedy plan, the MILP plan and the
hybrid (whichever covers more, the MILP on a tie), then the sums.

``--cli-runs N`` also times ``mushrooms plan`` (a fresh process, default
hybrid solver, default 30 s limit) on the first N maps and prints the median
wall time.  Not a test: nothing here asserts.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))  # benchmarks/common: the shared helpers
from csv_rows import write_rows  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data" / "skymaps"
DEFAULT_DIRS = [SHARED / "public", SHARED / "simulated" / "bns_o3"]


def sky_maps(paths: list[Path]) -> list[Path]:
    """Every ``*.fits`` / ``*.fits.gz`` under the given files or folders."""
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            out += sorted(q for q in p.iterdir() if q.name.endswith((".fits", ".fits.gz")))
        else:
            out.append(p)
    return out


def measure(path: Path, time_limit_s: float) -> dict:
    """Greedy, MILP and hybrid on one map; returns one table row."""
    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
    from mushrooms.scheduler_core.schedulers.blocks.schedule import milp_schedule

    cfg = PlanningConfig(time_limit_s=time_limit_s)
    sm = read_skymap(path, nside=cfg.nside)
    t = time.perf_counter()
    problem = prepare_problem(sm, cfg, sm.event_time)
    prep = time.perf_counter() - t
    greedy = greedy_schedule(problem)
    t = time.perf_counter()
    milp = milp_schedule(problem)
    milp_wall = time.perf_counter() - t

    def cov(result) -> float:
        return problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob)

    cg, cm = cov(greedy), cov(milp)
    valid, first_problem = check(sm, problem, milp, cfg)
    d = milp.details
    size = d.get("model_size", {})
    return {
        "map": path.name,
        "candidates": len(problem.field_ids),
        "shortlist": d.get("shortlist"),
        "pixels": d.get("n_pixels"),
        "cells": d.get("n_cells"),
        "vars": size.get("vars"), "int_vars": size.get("int_vars"), "rows": size.get("rows"),
        "nonzeros": size.get("nonzeros"),
        "backend": d.get("backend", ""),
        "t_first_s": d.get("time_to_first_s"),
        "t_1pct_s": d.get("time_to_gap_s"),
        "gap": milp.mip_gap,
        "status": milp.status,
        "retries": d.get("retries"),
        "dropped": len(milp.dropped_by_slews),
        "cov_greedy": cg, "cov_milp": cm, "cov_hybrid": cm if cm >= cg else cg,
        "prepare_s": prep, "greedy_s": greedy.runtime_s, "milp_s": milp_wall,
        "milp_valid": valid, "first_problem": first_problem,
    }


def check(skymap, problem, result, cfg) -> tuple[bool, str]:
    """Run the independent plan checker on a scheduler result."""
    from astropy.time import TimeDelta

    from mushrooms.scheduler_core import check_plan
    from mushrooms.scheduler_core.plan.document import Plan, PlanMetrics, sorted_observations

    obs = sorted_observations(result.observations)
    ids = {o.field_id for o in obs}
    metrics = PlanMetrics(coverage=problem.footprints.coverage(ids, problem.prob), solver=result.solver,
                          status=result.status, mip_gap=result.mip_gap, runtime_s=result.runtime_s,
                          n_fields=len(ids), n_exposures=len(obs))
    plan = Plan(plan_id="bench", start=problem.start, end=problem.start + TimeDelta(cfg.horizon_s, format="sec"),
                observations=obs, metrics=metrics)
    report = check_plan(plan, skymap, cfg)
    return report.ok, (report.problems[0] if report.problems else "")


def _fmt(v, spec: str) -> str:
    return "" if v is None else format(v, spec)


HEADER = (f"{'map':44s} {'pix':>6s} {'cells':>5s} {'vars/int/rows':>15s} {'first':>6s} {'1%':>6s} "
          f"{'gap':>7s} {'status':>11s} {'greedy':>7s} {'milp':>7s} {'hybrid':>7s} {'milp_s':>6s} ok")


def row_line(r: dict) -> str:
    size = f"{r['vars']}/{r['int_vars']}/{r['rows']}" if r["vars"] is not None else ""
    return (f"{r['map'][:44]:44s} {_fmt(r['pixels'], 'd'):>6s} {_fmt(r['cells'], 'd'):>5s} {size:>15s} "
            f"{_fmt(r['t_first_s'], '.2f'):>6s} {_fmt(r['t_1pct_s'], '.2f'):>6s} {_fmt(r['gap'], '.4f'):>7s} "
            f"{r['status'][:11]:>11s} {r['cov_greedy']:7.4f} {r['cov_milp']:7.4f} {r['cov_hybrid']:7.4f} "
            f"{r['milp_s']:6.1f} {'ok' if r['milp_valid'] else 'INVALID: ' + r['first_problem']}")


def cli_wall_times(paths: list[Path]) -> list[float]:
    """Wall time (s) of ``mushrooms plan MAP`` (defaults: hybrid, 30 s limit), one fresh process each."""
    times = []
    exe = [sys.executable, "-m", "mushrooms.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        for p in paths:
            t = time.perf_counter()
            proc = subprocess.run([*exe, "plan", str(p), "-o", str(Path(tmp) / "plan.json")],
                                  capture_output=True, text=True)
            times.append(time.perf_counter() - t)
            tail = (proc.stderr.strip().splitlines() or [""])[-1][:100]
            print(f"  cli {p.name}: {times[-1]:.1f} s rc={proc.returncode} {tail}", flush=True)
    return times


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="*", type=Path, default=DEFAULT_DIRS)
    ap.add_argument("--time-limit", type=float, default=30.0, help="MILP time limit (s)")
    ap.add_argument("--cli-runs", type=int, default=0, help="time `mushrooms plan` on the first N maps")
    ap.add_argument("-o", "--output", type=Path, help="also write the table as CSV")
    args = ap.parse_args(argv)

    maps = sky_maps(args.paths)
    rows = []
    print(HEADER, flush=True)
    for p in maps:
        try:
            r = measure(p, args.time_limit)
        except Exception as exc:  # a benchmark reports, it does not stop
            print(f"{p.name[:44]:44s} ERROR {type(exc).__name__}: {exc}", flush=True)
            continue
        rows.append(r)
        print(row_line(r), flush=True)
        if args.output:
            write_rows(args.output, rows)
    if rows:
        sg, sm, sh = (sum(r[k] for r in rows) for k in ("cov_greedy", "cov_milp", "cov_hybrid"))
        wins = sum(r["cov_milp"] > r["cov_greedy"] + 1e-4 for r in rows)
        losses = sum(r["cov_milp"] < r["cov_greedy"] - 1e-4 for r in rows)
        firsts = [r["t_first_s"] for r in rows if r["t_first_s"] is not None]
        reached = [r["t_1pct_s"] for r in rows if r["t_1pct_s"] is not None]
        print(f"{'SUM (' + str(len(rows)) + ' maps)':44s} {sum(r['pixels'] or 0 for r in rows):6d} "
              f"{sum(r['cells'] or 0 for r in rows):5d} {'':15s} {'':6s} {'':6s} {'':7s} {'':11s} "
              f"{sg:7.4f} {sm:7.4f} {sh:7.4f} {sum(r['milp_s'] for r in rows):6.1f}")
        print(f"MILP plans passing the checker: {sum(r['milp_valid'] for r in rows)}/{len(rows)}")
        print(f"MILP beats greedy on {wins} maps, loses on {losses}; hybrid >= greedy on all by construction")
        print(f"median time to first incumbent {statistics.median(firsts) if firsts else float('nan'):.2f} s; "
              f"1 % gap reached on {len(reached)}/{len(rows)} maps (median {statistics.median(reached) if reached else float('nan'):.2f} s)")
        print("statuses: " + ", ".join(f"{s} {sum(r['status'] == s for r in rows)}"
                                       for s in sorted({r['status'] for r in rows})))
    if args.cli_runs:
        times = cli_wall_times(maps[: args.cli_runs])
        print(f"median wall time of `mushrooms plan` (hybrid, {len(times)} maps): {statistics.median(times):.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
