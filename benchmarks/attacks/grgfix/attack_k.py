"""F10 on other sequences: k = 1, 3 (r-g-r), 4 (g-r-g-r), on a whole night and on the last 50 min; make_plan runs the checker."""
import dataclasses
from astropy.time import TimeDelta
from mushrooms.scheduler_core import PlanningConfig, read_skymap, make_plan
from collections import Counter
sky = read_skymap("/work/wt/grgfix/tests/data/skymaps/MS220722v_bayestar.multiorder.fits", nside=64)
for filters in (("g",), ("r", "g", "r"), ("g", "r", "g", "r"), ("g", "r", "g", "r", "g")):
    for label, off, h in (("whole night", 6 * 3600.0, 12.0), ("last 50 min", 13.9 * 3600 - 3000, 2.0), ("last 80 min", 13.9 * 3600 - 4800, 2.0)):
        cfg = PlanningConfig(solver="greedy", nside=64, filters=filters, exposure_s=180.0, horizon_h=h)
        try:
            plan = make_plan(sky, cfg, start=sky.event_time + TimeDelta(off, format="sec"))
            n = Counter(Counter(o.field_id for o in plan.observations).values())
            print("-".join(filters), label, f"coverage {plan.metrics.coverage:.4f}", "visits per field", sorted(n.items()))
        except Exception as exc:
            print("-".join(filters), label, "ERROR", type(exc).__name__, str(exc)[:200])
