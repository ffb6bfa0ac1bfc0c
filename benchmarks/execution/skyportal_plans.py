#!/usr/bin/env python
"""The SkyPortal target executed: per-pass SkyPortal plans vs one plan per revision, on the shared maps (T1).

For each shared map, night 1 from its event time is planned (greedy), its
SkyPortal plans are made as the daemon submits them (``to_skyportal_plans``,
``per_pass`` and ``single``), turned into the queues SkyPortal's ZTF API
sends (:func:`mushrooms.evaluation.skyportal_queue.skyportal_queue`) and
executed by the telescope model on a clear night, on time (Q14).  Prints one
JSON line per map: planned coverage, ``coverage_as_executed`` (the Kowalski
queue set), the per-pass SkyPortal plans' and the single plan's executed
cadence-valid coverage, and K.

    PYTHONPATH=. nice python benchmarks/execution/skyportal_plans.py [--nside 64] > rows.jsonl
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

MAPS = Path("/work/shared/data/skymaps")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nside", type=int, default=64)
    ap.add_argument("--maps", type=int, default=None, help="at most this many maps (sorted by path)")
    args = ap.parse_args(argv)
    from astropy.time import Time

    from mushrooms.evaluation.skyportal_queue import skyportal_queue
    from mushrooms.offline import configure_astropy_offline
    from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
    from mushrooms.scheduler_core.plan.exports import ExportConfig, to_skyportal_plans
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.schedulers.as_executed import queue_coverage

    configure_astropy_offline()
    config = PlanningConfig(solver="greedy", nside=args.nside)
    footprints = field_footprints(load_ztf_fields(), config.nside)
    per_pass, single = ExportConfig(skyportal_allocation_id=1), ExportConfig(skyportal_allocation_id=1,
                                                                             skyportal_plans="single")
    paths = sorted(p for p in MAPS.rglob("*") if p.name.endswith((".fits", ".fits.gz")))[:args.maps]
    for path in paths:
        try:
            skymap = read_skymap(path, nside=config.nside)
            plan = make_plan(skymap, config, Time(skymap.event_time, scale="utc")) if skymap.event_time else None
        except Exception as exc:  # a map the planner refuses: say so, go on
            print(json.dumps({"map": path.name, "status": f"skipped: {exc}"[:100]}), flush=True)
            continue
        if plan is None or not plan.observations or not plan.event.event_time:
            print(json.dumps({"map": path.name, "status": "no plan or no event time"}), flush=True)
            continue
        row = {"map": str(path.relative_to(MAPS)), "planned": round(plan.metrics.coverage, 6),
               "as_executed": round(plan.metrics.coverage_as_executed or 0.0, 6)}
        for name, export in (("skyportal_per_pass", per_pass), ("skyportal_single", single)):
            bodies = json.loads(json.dumps(to_skyportal_plans(plan, export)))  # as POSTed
            queues = [skyportal_queue(b) for b in bodies]
            row[name] = round(queue_coverage(plan, footprints, skymap.prob, queues=queues), 6)
            row[f"K_{name}"] = len(bodies)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
