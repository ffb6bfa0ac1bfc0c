"""Greedy and the hybrid under g-r-g at 180 s on every map given, at its event time (the checker runs in make_plan):
any PlanCheckError is a planner/checker disagreement (F10)."""
import sys, time
from mushrooms.scheduler_core import PlanningConfig, read_skymap, make_plan
from collections import Counter
bad = 0
for solver in sys.argv[1].split(","):
    cfg = PlanningConfig(filters=("g", "r", "g"), exposure_s=180.0, threads=1, solver=solver, time_limit_s=6.0,
                         detection_time_limit_s=2.0)
    for m in sys.argv[2:]:
        sky = read_skymap(m, nside=cfg.nside)
        try:
            plan = make_plan(sky, cfg, start=sky.event_time)
            n = Counter(Counter(o.field_id for o in plan.observations).values())
            print(solver, m.split('/')[-2][:16] + '/' + m.split('/')[-1][:24], f"{plan.metrics.coverage:.4f}", sorted(n.items()), flush=True)
        except Exception as exc:
            bad += 1
            print(solver, m, "ERROR", type(exc).__name__, str(exc)[:300], flush=True)
print("errors", bad)
