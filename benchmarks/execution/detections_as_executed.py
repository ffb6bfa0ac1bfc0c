"""Expected kilonova detections as ZTF's scheduler executes the default plan's queues, not only as planned.

``metrics.expected_detections`` (X1) scores the planned exposures; ``metrics.coverage_as_executed`` (Q14)
the queues as the executor runs them.  This scores X1 on the executed exposures too: each exposure the
executor completes (Q1-Q10, clear night, on time), at the time it starts, with the planned field's centre.
X1 takes each field's best exposure, so a field whose second visit the executor loses still counts once;
``expected_executed_pairs`` counts only the fields the executor took in both filters at least the cadence
apart (the pairs of Q14, what ZTF needs to tell a transient from a moving object).

Per map, the shipped configuration's default plan (``planner.optimise`` then ``build_plan``) under the tree
on ``PYTHONPATH``: planned coverage, executed coverage, expected detections planned, executed and in
executed pairs.

    PYTHONPATH=TREE python benchmarks/execution/detections_as_executed.py --out FILE.jsonl [MAP ...]
    python benchmarks/execution/detections_as_executed.py --compare BEFORE.jsonl AFTER.jsonl

Every *.fits / *.fits.gz under ../shared/data/skymaps/{public,simulated} unless maps are given; resumable.
``--compare`` prints the paired differences (mean ± s.e., maps better / worse).  Not a test.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))

from paired_maps import map_key, paired_rows, shared_maps  # noqa: E402


def run_map(path: Path, config_path: Path) -> dict:
    """One map's default plan, scored as planned and as executed."""
    import mushrooms
    from mushrooms.evaluation.loop import executed_detections
    from mushrooms.scheduler_core.executed import MIN_PROCESSED_FRACTION
    from mushrooms.scheduler_core.planner import build_plan, optimise
    from mushrooms.scheduler_core.prepare import prepare_problem
    from mushrooms.scheduler_core.sequences import covered_fields
    from mushrooms.scheduler_core.sky.fields import load_ztf_fields
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.scheduler_core.schedulers.as_executed import execute_plan_queues
    from mushrooms.tool.config import load_config

    cfg = load_config(config_path).scheduler
    sm = read_skymap(path, nside=cfg.nside)
    problem = prepare_problem(sm, cfg, sm.event_time)
    plan = build_plan(problem, optimise(problem, sm, cfg.solver), sm, cfg.solver)
    row = {"map": map_key(path), "tree": str(Path(mushrooms.__file__).parents[1]), "solver": plan.metrics.solver,
           "coverage": plan.metrics.coverage, "executed": plan.metrics.coverage_as_executed,
           "expected": plan.metrics.expected_detections, "expected_executed": None,
           "expected_executed_pairs": None, "load": os.getloadavg()[0]}
    if plan.observations and plan.metrics.expected_detections is not None:
        executed = execute_plan_queues(plan)
        grid = load_ztf_fields()

        def score(record) -> float | None:
            return executed_detections(record, plan, sm, problem.footprints, grid, cfg.detection_lightcurve)

        row["expected_executed"] = score(executed)
        # only the fields the executor took in both filters at least the cadence apart (Q14's pairs)
        paired = covered_fields(executed, cfg.filters, MIN_PROCESSED_FRACTION, cfg.cadence_s)
        row["expected_executed_pairs"] = score([e for e in executed if e.field_id in paired])
    return row


def compare(before: Path, after: Path) -> str:
    """Paired after - before over the maps both hold."""
    a = {r["map"]: r for r in map(json.loads, before.read_text().splitlines())}
    b = {r["map"]: r for r in map(json.loads, after.read_text().splitlines())}
    maps = sorted(set(a) & set(b))
    lines = [f"maps: {len(maps)}; {before.name} -> {after.name}"]
    for key in ("coverage", "executed", "expected", "expected_executed", "expected_executed_pairs"):
        pairs = [(a[m][key], b[m][key]) for m in maps if a[m][key] is not None and b[m][key] is not None]
        d = [y - x for x, y in pairs]
        se = statistics.stdev(d) / len(d) ** 0.5 if len(d) > 1 else float("nan")
        lines.append(f"{key:18s} mean {statistics.fmean(x for x, _ in pairs):.4f} -> {statistics.fmean(y for _, y in pairs):.4f}"
                     f"  after - before {statistics.fmean(d):+.4f} ± {se:.4f} "
                     f"({sum(x > 1e-4 for x in d)}/{sum(x < -1e-4 for x in d)}, n={len(d)})")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="*", type=Path)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--config", type=Path, default=Path(__file__).resolve().parents[2] / "config.toml")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"))
    args = ap.parse_args(argv)
    if args.compare:
        print(compare(*args.compare))
        return 0
    if args.out is None:
        ap.error("--out is needed to run the maps")

    def describe(row: dict) -> str:
        return (f"cov {row['coverage']:.4f} exec {row['executed'] or 0:.4f} E {row['expected'] or 0:.4f} "
                f"E exec {row['expected_executed'] or 0:.4f}")

    paired_rows(args.out, shared_maps(args.maps), lambda p, i: run_map(p, args.config), describe)
    return 0


if __name__ == "__main__":
    sys.exit(main())
