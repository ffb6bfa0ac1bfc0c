"""Issue 55, grgfix finding 3: a plan document through SkyPortal's ZTF API, one plan or one per filter pass.

    python benchmarks/attacks/grgfix/as_submitted_today.py PLAN.json SKYMAP

Executes (the telescope model) the plan's queue set, the one list queue SkyPortal makes of ONE observation plan
holding the whole plan, and the list queues it makes of the plans the service POSTs (one per filter pass, T1);
prints each run's cadence-valid coverage, and for the single list the g-r separations of the first fields.
"""

from __future__ import annotations

import json
import sys

from mushrooms.evaluation.queue_sim import submitted_today
from mushrooms.scheduler_core.plan.document import Plan
from mushrooms.scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.sky.skymap import read_skymap


def main(plan_path: str, skymap_path: str) -> None:
    plan = Plan.from_document(json.load(open(plan_path)))
    cfg = plan.config or {}
    filters, cadence = tuple(cfg.get("filters", ("g", "r")))[:2], float(cfg.get("cadence_s", 1800.0))
    sky = read_skymap(skymap_path, nside=int(cfg.get("nside", 256)))
    fp = field_footprints(load_ztf_fields(), sky.nside)
    print(f"plan {plan.plan_id}: {len(plan.observations)} exposures, coverage {plan.metrics.coverage:.4f}")
    for name, queues in (("queue set (Kowalski)", None), ("one SkyPortal plan: one list queue", submitted_today(plan)),
                         ("per-pass SkyPortal plans (T1)", submitted_today(plan, "per_pass"))):
        done = execute_plan_queues(plan, queues)
        cov = cadence_coverage(done, fp, sky.prob, filters, cadence)
        n = "" if queues is None else f", {len(queues)} list queue(s)"
        print(f"{name}{n}: {sum(e.status == 'processed' for e in done)} exposures done, coverage {cov:.4f}")
        if queues is not None and len(queues) == 1:
            first: dict[int, float] = {}
            gaps = []
            for e in sorted(done, key=lambda e: e.start.unix):
                if e.field_id in first and len(gaps) < 8:
                    gaps.append((e.field_id, round((e.start.unix - first[e.field_id]) / 60.0, 1)))
                first.setdefault(e.field_id, e.start.unix)
            print(f"  second visit after the first (min), cadence {cadence / 60:.0f} min: {gaps}")


if __name__ == "__main__":
    main(*sys.argv[1:3])
