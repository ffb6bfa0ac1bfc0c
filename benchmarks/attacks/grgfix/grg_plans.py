"""make_plan (the hybrid, default config) under g-r-g at 180 s on each map: planned, executed (Q14), whole sequences (Q21)."""
import sys
from mushrooms.scheduler_core import PlanningConfig, read_skymap, make_plan
cfg = PlanningConfig(filters=("g", "r", "g"), exposure_s=180.0, threads=1)
for m in sys.argv[1:]:
    sky = read_skymap(m, nside=cfg.nside)
    plan = make_plan(sky, cfg, start=sky.event_time)
    x = plan.metrics
    n = {}
    for o in plan.observations:
        n[o.field_id] = n.get(o.field_id, 0) + 1
    print(f"{m.split('/')[-1][:34]:34s} {x.solver:22s} planned {x.coverage:.4f} executed {x.coverage_as_executed or 0:.4f} "
          f"whole_seq {x.sequence_coverage_as_executed or 0:.4f} fields {len(n)} cut {sum(v == 2 for v in n.values())}", flush=True)
