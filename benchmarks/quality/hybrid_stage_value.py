"""What one of the hybrid's optional stages buys in the default plan, side by side with the hybrid without it.

Per map, the shipped configuration's whole optimisation (``planner.optimise``: the hybrid coverage stage,
then the detection stage) runs twice: with the stage's ``[scheduler]`` switch true and false, the arm that
goes first alternating per map.  ``--switch hybrid_blocks`` (arms ``blocks`` / ``no_blocks``): the block
MILP after the LNS; ``--switch hybrid_paced_slots`` (``paced`` / ``no_paced``): the slot portfolio at the
executor's cadence (Q19); ``--switch hybrid_lns`` (``lns`` / ``no_lns``): the LNS re-solves.  Per map and
arm: the optimisation's wall time, the published plan's coverage, expected detections (X1, the configured
light curve) and coverage as ZTF's scheduler executes it (``metrics.coverage_as_executed``), and the stage
whose plan the hybrid kept.

    python benchmarks/quality/hybrid_stage_value.py [--switch hybrid_blocks] [--out FILE] [MAP ...]

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

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks" / "common"))

from paired_maps import map_key, paired_rows, shared_maps, write_summary  # noqa: E402
#: switch -> its arms (on, off)
SWITCHES = {"hybrid_blocks": ("blocks", "no_blocks"), "hybrid_paced_slots": ("paced", "no_paced"),
            "hybrid_lns": ("lns", "no_lns")}


def run_map(path: Path, first: int, switch: str) -> dict:
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
    arms = list(SWITCHES[switch])
    for arm in arms[first:] + arms[:first]:
        arm_problem = dataclasses.replace(problem, config=dataclasses.replace(cfg, **{switch: arm == arms[0]}))
        t0 = time.perf_counter()
        result = optimise(arm_problem, sm, cfg.solver)
        wall = time.perf_counter() - t0
        m = build_plan(arm_problem, result, sm, cfg.solver).metrics
        row[arm] = {"wall_s": round(wall, 3), "coverage": m.coverage, "expected": m.expected_detections or 0.0,
                    "executed": m.coverage_as_executed, "kept": result.solver,
                    "choice": result.portfolio_choice,
                    "stage_times_s": result.details.get("stage_times_s")}
    row["load"] = os.getloadavg()[0]
    return row


def paired(rows: list[dict], key: str, on: str, off: str) -> str:
    """``off - on``: mean ± s.e. over maps (maps better / worse beyond 1e-4)."""
    d = [(r[off][key] or 0.0) - (r[on][key] or 0.0) for r in rows]
    n = len(d)
    se = statistics.stdev(d) / n ** 0.5 if n > 1 else float("nan")
    return (f"{sum(d) / n:+.4f} ± {se:.4f} ({sum(x > 1e-4 for x in d)}/{sum(x < -1e-4 for x in d)}), "
            f"worst {min(d):+.4f}")


def summary(rows: list[dict], switch: str) -> str:
    """Walls per arm and the paired differences."""
    on, off = SWITCHES[switch]
    lines = [f"maps: {len(rows)}; load (1-min) at each map: median {statistics.median(r['load'] for r in rows):.1f}, "
             f"max {max(r['load'] for r in rows):.1f}"]
    for arm in (on, off):
        walls = sorted(r[arm]["wall_s"] for r in rows)
        p95 = walls[min(len(walls) - 1, int(round(0.95 * (len(walls) - 1))))]
        lines.append(f"{arm:10} optimisation wall p50 {statistics.median(walls):.2f} s, mean "
                     f"{statistics.fmean(walls):.2f} s, p95 {p95:.2f} s; coverage mean "
                     f"{statistics.fmean(r[arm]['coverage'] for r in rows):.4f}, E mean "
                     f"{statistics.fmean(r[arm]['expected'] for r in rows):.4f}, executed mean "
                     f"{statistics.fmean((r[arm]['executed'] or 0.0) for r in rows):.4f}")
    saved = [r[on]["wall_s"] - r[off]["wall_s"] for r in rows]
    lines.append(f"wall saved by {off}: median {statistics.median(saved):.2f} s, mean {statistics.fmean(saved):.2f} s")
    for key in ("coverage", "expected", "executed"):
        lines.append(f"{off} - {on}, {key}: {paired(rows, key, on, off)}")
    if switch == "hybrid_paced_slots":
        kept = [r["map"] for r in rows if r[on].get("choice") == "slots_paced"]
        lines.append(f"the paced slot plan kept by the hybrid on {len(kept)} maps")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*", type=Path)
    ap.add_argument("--switch", choices=sorted(SWITCHES), default="hybrid_blocks")
    ap.add_argument("--out", type=Path, help="default benchmarks/results/speed/runs/<switch>_value.jsonl")
    args = ap.parse_args(argv)
    out = args.out or ROOT / "benchmarks" / "results" / "speed" / "runs" / f"{args.switch}_value.jsonl"

    def describe(row: dict) -> str:
        return "  ".join(f"{a} {row[a]['wall_s']:.2f} s cov {row[a]['coverage']:.4f} E {row[a]['expected']:.4f}"
                         f" exec {row[a]['executed'] or 0.0:.4f}" for a in SWITCHES[args.switch])

    rows = paired_rows(out, shared_maps(args.maps), lambda path, i: run_map(path, i % 2, args.switch), describe)
    text = summary(rows, args.switch)
    write_summary(out, f"the default's optimisation with and without {args.switch}, arms alternating first", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
