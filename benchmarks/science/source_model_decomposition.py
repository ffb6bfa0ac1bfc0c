"""Decompose the change of scoring: early-time light curve (K1) vs sky-dependent depth (D1).

Greedy plans (deterministic) of every sky map in a directory, scored four ways on the same
injections: first release (table-only light curve, flat 300 s limits), early-time curve only,
sky-dependent depth only, both.

    nice -n 5 .venv/bin/python benchmarks/science/source_model_decomposition.py MAP_DIR OUT.csv
"""
import sys, glob, numpy as np
from astropy.utils import iers
iers.conf.auto_download = False
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.sky.skymap import read_skymap
from mushrooms.scheduler_core.planner import make_plan
from mushrooms.evaluation.efficiency import draw_injections, detected, DEFAULT_MAGLIM_300S
from mushrooms.scheduler_core.source.kilonova import Kilonova
from mushrooms.scheduler_core.source.lightcurves import load_lightcurve
from mushrooms.scheduler_core.source.depth import ZTF_DEPTH
from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
fp = field_footprints(load_ztf_fields(), 256)
cfg = PlanningConfig()
out = open(sys.argv[2], "w")
print("map,lc,v1,early_only,depth_only,new", file=out, flush=True)
for path in sorted(glob.glob(sys.argv[1] + "/*")):
    sm = read_skymap(path, nside=256)
    plan = make_plan(sm, cfg, solver="greedy")
    inj = draw_injections(sm, 10000)
    for name in ("optimistic", "conservative"):
        lc = load_lightcurve(name); kn = Kilonova(lc)
        v = [detected(plan, a, fp, inj, sm.event_time, b).mean() for a, b in
             ((lc, DEFAULT_MAGLIM_300S), (kn, DEFAULT_MAGLIM_300S), (lc, ZTF_DEPTH), (kn, ZTF_DEPTH))]
        print(path.split("/")[-1], name, *[f"{x:.4f}" for x in v], sep=",", file=out, flush=True)
