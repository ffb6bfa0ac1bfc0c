#!/usr/bin/env python
"""Which queue export ZTF's scheduler follows best: the executor model (Q1-Q10) on plans of the shared maps.

For each map, night 1 from its event time is planned (``--solver``, default
greedy), exported as the old single list queue and as timed per-pass queues
with several window slacks (``passes_<slack>``: wide closes; ``robust_<slack>``: closes chosen for a
late or off-speed telescope, Q16-Q18), and each export is executed on a clear night,
on time and with the telescope free 15/30/60 min late.  Prints one JSON line
per map and variant: planned coverage and the cadence-valid executed one.

    PYTHONPATH=. nice python benchmarks/execution/queue_variants.py [--maps N] [--nside 128] [--solver greedy]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

MAPS = Path("/work/shared/data/skymaps")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--maps", type=int, default=None)
    ap.add_argument("--nside", type=int, default=128)
    ap.add_argument("--solver", default="greedy")
    ap.add_argument("--time-limit", type=float, default=None)
    ap.add_argument("--slacks", default="120,600,1800")
    ap.add_argument("--late", default="0,900,1800,3600")
    ap.add_argument("--speeds", default="0.8,1.2", help="telescope overheads x these factors, on time")
    args = ap.parse_args(argv)
    import dataclasses

    from astropy.time import Time, TimeDelta

    from mushrooms.evaluation.queue_sim import achieved_coverage
    from mushrooms.offline import configure_astropy_offline
    from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
    from mushrooms.scheduler_core.plan.exports import to_trigger_queue, to_trigger_queues
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.telescope.executor import (execute_queues, executed_exposures,
                                                             queue_set_from_payloads)
    from mushrooms.scheduler_core.telescope.timing import TelescopeTiming

    configure_astropy_offline()
    config = PlanningConfig(solver=args.solver, nside=args.nside)
    if args.time_limit:
        config = dataclasses.replace(config, time_limit_s=args.time_limit)
    footprints = field_footprints(load_ztf_fields(), config.nside)
    paths = sorted(p for p in MAPS.rglob("*") if p.name.endswith((".fits", ".fits.gz")))
    if args.maps:
        step = len(paths) / args.maps
        paths = [paths[int(i * step)] for i in range(args.maps)]
    slacks = [float(s) for s in args.slacks.split(",")]
    lates = [float(x) for x in args.late.split(",")]
    speeds = [float(x) for x in args.speeds.split(",") if x]
    for path in paths:
        t0 = time.perf_counter()
        try:
            skymap = read_skymap(path, nside=config.nside)
            if skymap.event_time is None:
                continue
            plan = make_plan(skymap, config, Time(skymap.event_time, scale="utc"))
        except Exception as exc:  # a map the planner refuses: say so, go on
            print(json.dumps({"map": path.name, "status": f"skipped: {exc}"[:100]}), flush=True)
            continue
        if not plan.observations:
            print(json.dumps({"map": path.name, "status": "empty plan"}), flush=True)
            continue
        exports = {"single": [to_trigger_queue(plan)]}
        export_s = {}
        for s in slacks:
            exports[f"passes_{int(s)}"] = to_trigger_queues(plan, slack_s=s, robust=False)
            t_export = time.perf_counter()
            exports[f"robust_{int(s)}"] = to_trigger_queues(plan, slack_s=s)
            export_s[f"export_s_robust_{int(s)}"] = round(time.perf_counter() - t_export, 2)
        first = plan.observations[0].start
        end = float((plan.end - plan.start).to_value("s"))
        row = {"map": str(path.relative_to(MAPS)), "planned": plan.metrics.coverage,
               "n_obs": len(plan.observations), "plan_s": round(time.perf_counter() - t0, 1), **export_s}
        for late in lates:  # what the plan holds after the telescope is free: the time lost, no more
            kept = {o.field_id for o in plan.observations if o.start >= first + late}
            pairs = {f for f in kept if sum(1 for o in plan.observations if o.field_id == f and o.start >= first + late) >= 2}
            row[f"after@{int(late / 60)}"] = round(footprints.coverage(sorted(pairs), skymap.prob), 6) if pairs else 0.0
        for name, queues in exports.items():
            qs = queue_set_from_payloads(queues, plan.start)
            row[f"K_{name}"] = len(queues)
            for late in lates:
                done = execute_queues(qs, plan.start, first + late, end)
                ex = executed_exposures(qs, done, plan.start)
                row[f"{name}@{int(late / 60)}"] = round(achieved_coverage(ex, skymap, footprints,
                                                                          filters=config.filters,
                                                                          cadence_s=config.cadence_s), 6)
            for speed in speeds:  # a telescope slower/faster than modelled, on time
                timing = TelescopeTiming().scaled(speed)
                done = execute_queues(qs, plan.start, first, end, timing)
                ex = executed_exposures(qs, done, plan.start)
                row[f"{name}@x{speed:g}"] = round(achieved_coverage(ex, skymap, footprints, filters=config.filters,
                                                                      cadence_s=config.cadence_s), 6)
        row["total_s"] = round(time.perf_counter() - t0, 1)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
