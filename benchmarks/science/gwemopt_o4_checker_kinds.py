#!/usr/bin/env python3
"""Which of the checker's rules gwemopt's named configurations break, per map (issue 55 pilot), from the cache.

For each pilot map and each of ``gwemopt-o4`` and ``gwemopt-skyportal`` (and the first release's ``gwemopt``), the
cached raw schedule (never running gwemopt: ``gwemopt_cache_only``) is wrapped as the bench wraps it and checked
under the configuration with the row's filter sequence and exposure; prints the problem counts per kind
(``window``, ``slew``, ``overlap``, ``cadence``, ``sequence``, ...).

    .venv/bin/python benchmarks/science/gwemopt_o4_checker_kinds.py [--maps bns_o3/0.fits ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from astropy.time import Time
from astropy.utils import iers

from mushrooms.evaluation.gwemopt_baseline import gwemopt_plan, run_gwemopt
from mushrooms.evaluation.gwemopt_options import GWEMOPT_CONFIGS, credible_fields, row_planning_config
from mushrooms.scheduler_core.plan.checker import check_plan
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
from mushrooms.scheduler_core.sky.skymap import read_skymap
from mushrooms.tool.config import load_config

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def main() -> int:
    from gwemopt_o4_pilot import DEFAULT_MAPS, SIMULATED

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=list(DEFAULT_MAPS))
    ap.add_argument("--cache", type=Path, default=ROOT / "benchmarks/results/science/gwemopt-cache")
    args = ap.parse_args()
    iers.conf.auto_download = False
    cfg = load_config(ROOT / "config.toml").scheduler
    fp = field_footprints(load_ztf_fields(), cfg.nside)
    for rel in args.maps:
        path = SIMULATED / rel
        sm = read_skymap(path, nside=cfg.nside)
        start = Time(sm.event_time, scale="utc")
        for name in ("gwemopt", "gwemopt-o4", "gwemopt-skyportal"):
            named = GWEMOPT_CONFIGS[name]
            fields = credible_fields(fp, sm.prob, named.credible_fields) if named.credible_fields else None
            run = run_gwemopt(path, start, cfg, cache_dir=args.cache, cache_only=True, named=named, fields=fields)
            if run.status != "ok":
                print(f"{rel} {name}: {run.status}")
                continue
            rcfg = row_planning_config(cfg, named)
            ids = {o.field_id for o in run.observations}
            plan = gwemopt_plan(run, start, rcfg, sm.sha256, fp.coverage(ids, sm.prob) if ids else 0.0, name=name)
            report = check_plan(plan, sm, rcfg)
            kinds = ", ".join(f"{k} {v}" for k, v in sorted(report.counts.items())) or "none"
            print(f"{rel} {name}: {len(plan.observations)} exposures, {len(ids)} fields; problems: {kinds}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
