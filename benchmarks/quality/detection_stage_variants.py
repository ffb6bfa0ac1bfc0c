"""Variants of the detection stage side by side on the same coverage plans: where its time goes, what it buys.

Per map: the shipped configuration's coverage stage (the hybrid, ``time_limit_s - detection_time_limit_s``)
runs once; the detection stage then runs on that same coverage plan once per arm, the arm that goes first
alternating per map (a slow spell of a shared machine falls on both).  An arm sets the stage's module
constants or its budget: ``base`` (as shipped), ``grids=K`` (``MAX_GRIDS``: at most K grids, the coverage
plan's own first), ``budget=S`` (S s instead of ``detection_time_limit_s``); joined with commas.  Per map and arm:
the stage's wall time, the published coverage and expected detections (X1, the configured light curve) of
the plan it returns, which grid's plan it kept, each grid's status, solve time and when it last gained
``min_gain``.

    python benchmarks/quality/detection_stage_variants.py [--arms base grids=1 grids=2] [--out FILE] [MAP ...]

Every *.fits / *.fits.gz under ../shared/data/skymaps/{public,simulated} unless maps are given.  The
summary (paired differences against None: mean ± s.e., maps better / worse) goes to FILE.summary.txt.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks" / "common"))

from paired_maps import map_key, paired_rows, shared_maps, write_summary  # noqa: E402


def set_arm(stage_module, arm: str, shipped: int | None) -> None:
    """Set the detection stage's constants for ``arm`` (``base``, ``grids=K``, ``budget=S``); ``shipped``: MAX_GRIDS."""
    stage_module.MAX_GRIDS = shipped
    for part in arm.split(","):
        if part.startswith("budget="):
            continue  # :func:`arm_budget`
        if part.startswith("grids="):
            stage_module.MAX_GRIDS = int(part[6:])
        elif part != "base":
            raise SystemExit(f"unknown arm {arm!r}")


def arm_budget(arm: str, default: float) -> float:
    """The stage's budget (s) in ``arm``."""
    return next((float(p[7:]) for p in arm.split(",") if p.startswith("budget=")), default)


def run_map(path: Path, arms: list[str], first: int) -> dict:
    """One map: the coverage plan once, then the detection stage per arm (starting with ``arms[first]``)."""
    from mushrooms.scheduler_core.planner import coverage_stage_problem, greedy_coverage, run_scheduler
    from mushrooms.scheduler_core.prepare import prepare_problem
    from mushrooms.scheduler_core.schedulers.detection import stage as detection_slots
    from mushrooms.scheduler_core.schedulers.gain import published_coverage
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.tool.config import load_config

    cfg = load_config(ROOT / "config.toml").scheduler
    sm = read_skymap(path, nside=cfg.nside)
    problem = prepare_problem(sm, cfg, sm.event_time)
    cov = run_scheduler(coverage_stage_problem(problem), cfg.solver)
    row: dict = {"map": map_key(path), "coverage_plan": published_coverage(problem, cov),
                 "greedy": greedy_coverage(cov)}
    shipped = detection_slots.MAX_GRIDS
    for arm in arms[first:] + arms[:first]:
        set_arm(detection_slots, arm, shipped)
        t0 = time.perf_counter()
        det = detection_slots.detection_stage(problem, sm, cov, time_limit_s=arm_budget(arm, cfg.detection_time_limit_s),
                                              baseline_coverage=row["greedy"])
        wall = time.perf_counter() - t0
        grids = [g for g in det.detection.grids if "status" in g] if det.detection else []
        e = float(det.expected_detections or 0.0)
        kept = None
        if det.detection and det.detection.choice == "detection":
            kept = next((i for i, g in enumerate(grids) if g.get("above_floor")
                         and abs(g.get("expected_detections", -1.0) - e) < 1e-12), None)
        row[arm] = {
            "wall_s": round(wall, 3), "coverage": published_coverage(problem, det), "expected": e,
            "choice": det.detection.choice if det.detection else None, "kept_grid": kept,
            "grids": [(g["grid"], g["status"], g.get("runtime_s"), g.get("last_gain_s")) for g in grids]}
    row["load"] = os.getloadavg()[0]
    return row


def paired(rows: list[dict], a: str, b: str, key: str) -> tuple[float, float, int, int]:
    """Mean and standard error of ``b - a`` over maps, maps better and worse (beyond 1e-4)."""
    d = [r[b][key] - r[a][key] for r in rows]
    n = len(d)
    mean = sum(d) / n
    se = statistics.stdev(d) / n ** 0.5 if n > 1 else float("nan")
    return mean, se, sum(x > 1e-4 for x in d), sum(x < -1e-4 for x in d)


def summary(rows: list[dict], arms: list[str]) -> str:
    """The paired table against the first arm."""
    base = arms[0]
    lines = [f"maps: {len(rows)}; load (1-min) at each map: median {statistics.median(r['load'] for r in rows):.1f}, "
             f"max {max(r['load'] for r in rows):.1f}",
             f"{'arm':10} {'wall p50':>8} {'wall mean':>9} {'wall p95':>8} {'E mean':>8} {'cov mean':>9}   "
             f"{'E - ' + base:>26} {'coverage - ' + base:>26}"]
    for arm in arms:
        name = arm
        walls = sorted(r[name]["wall_s"] for r in rows)
        p95 = walls[min(len(walls) - 1, int(round(0.95 * (len(walls) - 1))))]
        e = statistics.fmean(r[name]["expected"] for r in rows)
        c = statistics.fmean(r[name]["coverage"] for r in rows)
        if name == base:
            cols = f"{'':>26} {'':>26}"
        else:
            me, se, up, dn = paired(rows, base, name, "expected")
            mc, sc, cu, cd = paired(rows, base, name, "coverage")
            cols = f"{f'{me:+.4f} ± {se:.4f} ({up}/{dn})':>26} {f'{mc:+.4f} ± {sc:.4f} ({cu}/{cd})':>26}"
        lines.append(f"{name:10} {statistics.median(walls):8.2f} {statistics.fmean(walls):9.2f} {p95:8.2f} "
                     f"{e:8.4f} {c:9.4f}   {cols}")
    below = [r["map"] for r in rows for arm in arms if r["greedy"] is not None
             and r[arm]["coverage"] < r["greedy"] - 1e-9]
    lines.append(f"plans covering less than greedy's: {len(below)} {below}")
    for arm in arms:
        kept = [r[arm]["kept_grid"] for r in rows if r[arm]["kept_grid"] is not None]
        lines.append(f"{arm}: detection plan kept on {len(kept)} maps, from grid #"
                     + ", #".join(f"{k}: {kept.count(k)}" for k in sorted(set(kept))))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*", type=Path)
    ap.add_argument("--arms", nargs="+", default=["base", "grids=1", "grids=2"],
                    help="base, grids=K, budget=S (joined with commas); the first is the reference")
    ap.add_argument("--out", type=Path,
                    default=ROOT / "benchmarks" / "results" / "speed" / "runs" / "detection_stage_variants.jsonl")
    args = ap.parse_args(argv)
    arms: list[str] = args.arms

    def describe(row: dict) -> str:
        return "  ".join(f"{a} {row[a]['wall_s']:.2f} s E {row[a]['expected']:.4f}"
                         for a in arms)

    rows = paired_rows(args.out, shared_maps(args.maps), lambda path, i: run_map(path, arms, i % len(arms)), describe)
    text = summary(rows, arms)
    write_summary(args.out, "the detection stage on the same coverage plan per map, arms alternating first", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
