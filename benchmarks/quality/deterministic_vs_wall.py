"""The default optimisation on the work budget against the wall budget, paired per map (issue 55, item 1).

Per map, the shipped configuration's whole optimisation (``planner.optimise``: the hybrid coverage stage, then the
detection stage) runs twice, ``[scheduler] deterministic`` true (work seconds) and false (wall seconds), the arm
going first alternating per map.  Per map and arm: wall time, CPU seconds of the thread (what the arm got of the
machine), the published plan's coverage, expected detections (X1, the configured light curve), coverage as ZTF's
scheduler executes it, the work spent (work arm) and the load.  Summary: wall and CPU medians per arm, and the
paired differences ``work - wall`` (mean ± s.e., maps better / worse beyond 1e-4).

    python benchmarks/quality/deterministic_vs_wall.py [--out FILE] [MAP ...]     (default: eight shared maps)

Resumable (maps already in FILE are skipped); the summary goes to FILE.summary.txt.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
#: ../shared/data/skymaps from the checkout (or from a worktree one level deeper)
SKYMAPS = next((p / "shared" / "data" / "skymaps" for p in ROOT.parents if (p / "shared" / "data").is_dir()),
               ROOT.parent / "shared" / "data" / "skymaps")
DEFAULT_MAPS = ["public/G476954_bayestar.fits.gz", "public/S191216ap_bayestar.multiorder.fits",
                "public/M403699_bayestar.multiorder.fits", "public/S230627c_Bilby.multiorder.fits",
                "public/obs-scenarios_sim6_HKL.multiorder.fits", "public/MS220722v_bayestar.multiorder.fits",
                "simulated/bns_o3/11.fits", "simulated/bns_o3/18.fits"]
ARMS = ("work", "wall")
OUT = ROOT / "benchmarks" / "results" / "quality" / "deterministic_budget" / "deterministic_vs_wall.jsonl"


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
    row: dict = {"map": f"{path.parent.name}/{path.name}"}
    for arm in ARMS[first:] + ARMS[:first]:
        arm_cfg = dataclasses.replace(cfg, deterministic=arm == "work")
        arm_problem = dataclasses.replace(problem, config=arm_cfg)
        load = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), time.thread_time()
        result = optimise(arm_problem, sm, cfg.solver)
        wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
        m = build_plan(arm_problem, result, sm, cfg.solver).metrics
        row[arm] = {"wall_s": round(wall, 3), "cpu_s": round(cpu, 3), "load": round(load, 2),
                    "coverage": m.coverage, "expected": m.expected_detections or 0.0,
                    "executed": m.coverage_as_executed, "kept": result.solver, "budget": m.budget,
                    "stage_times_s": result.details.get("stage_times_s")}
    return row


def paired(rows: list[dict], key: str) -> str:
    """``work - wall``: mean ± s.e. over maps (maps better / worse beyond 1e-4), the worst."""
    d = [(r["work"][key] or 0.0) - (r["wall"][key] or 0.0) for r in rows]
    se = statistics.stdev(d) / len(d) ** 0.5 if len(d) > 1 else float("nan")
    return (f"{sum(d) / len(d):+.4f} ± {se:.4f} ({sum(x > 1e-4 for x in d)} better / {sum(x < -1e-4 for x in d)} "
            f"worse), worst {min(d):+.4f}, best {max(d):+.4f}")


def summary(rows: list[dict]) -> str:
    lines = [f"maps: {len(rows)}"]
    for arm in ARMS:
        walls = [r[arm]["wall_s"] for r in rows]
        cpus = [r[arm]["cpu_s"] for r in rows]
        loads = [r[arm]["load"] for r in rows]
        lines.append(f"{arm}: wall median {statistics.median(walls):.2f} s (max {max(walls):.2f}), cpu median "
                     f"{statistics.median(cpus):.2f} s, load (1-min) median {statistics.median(loads):.1f} "
                     f"(max {max(loads):.1f})")
    spent = [r["work"]["budget"]["spent"] for r in rows]
    lines.append(f"work spent: median {statistics.median(spent):.2f} work_s (max {max(spent):.2f})")
    for key in ("coverage", "expected", "executed"):
        lines.append(f"{key} (work - wall): {paired(rows, key)}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("maps", nargs="*", type=Path)
    args = parser.parse_args()
    maps = args.maps or [SKYMAPS / m for m in DEFAULT_MAPS]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    done = {}
    if args.out.exists():
        done = {json.loads(line)["map"]: json.loads(line) for line in args.out.read_text().splitlines() if line}
    rows = []
    with open(args.out, "a") as fh:
        for i, path in enumerate(maps):
            key = f"{path.parent.name}/{path.name}"
            if key in done:
                rows.append(done[key])
                continue
            row = run_map(path, i % 2)
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            rows.append(row)
            print(f"[{i + 1}/{len(maps)}] {key}: " + "; ".join(
                f"{a} {row[a]['wall_s']:.1f} s cov {row[a]['coverage']:.4f} E {row[a]['expected']:.4f} "
                f"(load {row[a]['load']:.1f})" for a in ARMS), file=sys.stderr, flush=True)
    text = summary(rows)
    Path(f"{args.out}.summary.txt").write_text(
        f"# {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} {os.cpu_count()} cores; "
        f"deterministic_vs_wall.py, the shipped config.toml\n{text}\n")
    print(text)


if __name__ == "__main__":
    main()
