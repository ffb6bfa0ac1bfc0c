"""Reproduction: where does test_a_detection_plan_that_loses_pairs_as_executed_is_not_published's premise hold?

The test's problem: MS220722v, a 2 h horizon from ``OFFSET`` s before greedy's first exposure; the paced slot plan
(1.5 s) is the coverage plan, then the detection stage.  The premise: some grid's plan has more expected
detections and keeps the coverage floor as planned but not as executed (X10), so the stage refuses it.  Printed
per offset and detection budget: the grids' statuses and whether the premise holds, on the budget given.

    python benchmarks/attacks/paced_premise_search.py [--deterministic true|false] [--offsets 600,900,1200]
                                                      [--budgets 0.5,1.5,3,6]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--deterministic", choices=("true", "false"), default="true")
    parser.add_argument("--offsets", default="600,900,1200")
    parser.add_argument("--budgets", default="0.5,1.5,3,6")
    args = parser.parse_args()
    from astropy.time import Time, TimeDelta

    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import run_scheduler
    from mushrooms.scheduler_core.schedulers.detection.stage import detection_stage
    from mushrooms.scheduler_core.schedulers.portfolio.portfolio import paced_slots_stage
    from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverage_as_executed

    det = args.deterministic == "true"
    sm = read_skymap(ROOT / "tests" / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=256)
    full = prepare_problem(sm, PlanningConfig(milp_backend="highs", threads=1, deterministic=det),
                           Time(sm.event_time, scale="utc"))
    first = min(o.start for o in run_scheduler(full, "greedy").observations)
    for offset in (float(x) for x in args.offsets.split(",")):
        cfg = PlanningConfig(milp_backend="highs", threads=1, time_limit_s=6.0, detection_time_limit_s=3.0,
                             horizon_h=2.0, deterministic=det)
        problem = prepare_problem(sm, cfg, full.start + TimeDelta(first - offset, format="sec"))
        coverage = paced_slots_stage(problem, None, {}, 1.5)
        floor = (1 - cfg.detection_max_coverage_loss) * keyed_coverage_as_executed(problem, coverage)[1]
        for budget in (float(x) for x in args.budgets.split(",")):
            r = detection_stage(problem, sm, coverage, time_limit_s=budget)
            refused = [g for g in r.detection.grids if g.get("above_executed_floor") is False]
            holds = bool(refused) and all(g["above_floor"] and g["coverage_as_executed"] < floor for g in refused) \
                and all(g["expected_detections"] > r.detection.expected_detections_coverage for g in refused)
            grids = " ".join(f"{g['grid']}:{g.get('status')}" + ("(refused as executed)" if g in refused else "")
                             for g in r.detection.grids)
            print(f"offset {offset:5.0f} s, detection budget {budget:4.1f}: premise {'holds' if holds else 'fails'}; "
                  f"{grids}", flush=True)


if __name__ == "__main__":
    main()
