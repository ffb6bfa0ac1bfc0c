"""What the hybrid's block MILP stage buys in the default plan, side by side with the hybrid without it.

Per map, the shipped configuration's whole optimisation (``planner.optimise``: the hybrid coverage stage,
then the detection stage) runs twice: with ``[scheduler] hybrid_blocks = true`` (greedy, slots, LNS, blocks)
and false (no block stage), the arm that goes first alternating per map.  Per map and arm: the
optimisation's wall time, the published plan's coverage, expected detections (X1, the configured light
curve) and coverage as ZTF's scheduler executes it (``metrics.coverage_as_executed``), and the stage whose
plan the hybrid kept.

    python benchmarks/block_stage_value.py [--out FILE] [MAP ...]

Every *.fits / *.fits.gz under ../shared/data/skymaps/{public,simulated} unless maps are given; resumable
(maps already in FILE are skipped).  The paired summary goes to FILE.summary.txt.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from paired_maps import map_key, paired_rows, shared_maps, write_summary  # noqa: E402
#: arm -> ``hybrid_blocks``
ARMS = {"blocks": True, "no_blocks": False}


def run_map(path: Path, first: int) -> dict:
    """One map, both arms (starting with the ``first``-th)."""
    import dataclasses

    from mushrooms.scheduler_core.planner import build_plan, optimise
    from mushrooms.scheduler_core.prepare import prepare_problem
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.tool.config import load_config

    cfg = load_config(ROOT / "config.toml").scheduler
    sm = read_skymap(path, nside=cfg.nside)
    problem = prepare_problem(sm, cfg, sm.event_time)
    row: dict = {"map": map_key(path)}
    arms = list(ARMS)
    for arm in arms[first:] + arms[:first]:
        arm_problem = dataclasses.replace(problem, config=dataclasses.replace(cfg, hybrid_blocks=ARMS[arm]))
        t0 = time.perf_counter()
        result = optimise(arm_problem, sm, cfg.solver)
        wall = time.perf_counter() - t0
        m = build_plan(arm_problem, result, sm, cfg.solver).metrics
        row[arm] = {"wall_s": round(wall, 3), "coverage": m.coverage, "expected": m.expected_detections or 0.0,
                    "executed": m.coverage_as_executed, "kept": result.solver,
                    "stage_times_s": result.details.get("stage_times_s")}
    row["load"] = os.getloadavg()[0]
    return row


def paired(rows: list[dict], key: str) -> str:
    """``no_blocks - blocks``: mean ± s.e. over maps (maps better / worse beyond 1e-4)."""
    d = [(r["no_blocks"][key] or 0.0) - (r["blocks"][key] or 0.0) for r in rows]
    n = len(d)
    se = statistics.stdev(d) / n ** 0.5 if n > 1 else float("nan")
    return (f"{sum(d) / n:+.4f} ± {se:.4f} ({sum(x > 1e-4 for x in d)}/{sum(x < -1e-4 for x in d)}), "
            f"worst {min(d):+.4f}")


def summary(rows: list[dict]) -> str:
    """Walls per arm and the paired differences."""
    lines = [f"maps: {len(rows)}; load (1-min) at each map: median {statistics.median(r['load'] for r in rows):.1f}, "
             f"max {max(r['load'] for r in rows):.1f}"]
    for arm in ARMS:
        walls = sorted(r[arm]["wall_s"] for r in rows)
        p95 = walls[min(len(walls) - 1, int(round(0.95 * (len(walls) - 1))))]
        lines.append(f"{arm:10} optimisation wall p50 {statistics.median(walls):.2f} s, mean "
                     f"{statistics.fmean(walls):.2f} s, p95 {p95:.2f} s; coverage mean "
                     f"{statistics.fmean(r[arm]['coverage'] for r in rows):.4f}, E mean "
                     f"{statistics.fmean(r[arm]['expected'] for r in rows):.4f}, executed mean "
                     f"{statistics.fmean((r[arm]['executed'] or 0.0) for r in rows):.4f}")
    saved = [r["blocks"]["wall_s"] - r["no_blocks"]["wall_s"] for r in rows]
    lines.append(f"wall saved without blocks: median {statistics.median(saved):.2f} s, mean {statistics.fmean(saved):.2f} s")
    for key in ("coverage", "expected", "executed"):
        lines.append(f"no_blocks - blocks, {key}: {paired(rows, key)}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*", type=Path)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "speed" / "block_stage_value.jsonl")
    args = ap.parse_args(argv)
    def describe(row: dict) -> str:
        return "  ".join(f"{a} {row[a]['wall_s']:.2f} s cov {row[a]['coverage']:.4f} E {row[a]['expected']:.4f}"
                         for a in ARMS)

    rows = paired_rows(args.out, shared_maps(args.maps), lambda path, i: run_map(path, i % 2), describe)
    text = summary(rows)
    write_summary(args.out, "the default's optimisation with and without the hybrid's block stage, arms alternating first", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
