"""Menu off = the plans of before: run in two trees (this branch and main) and diff the output.

For the test map and one shared simulated map (nside 64): the greedy plan id and a hash of its exposures, a
hash of the first slot grid detection model (A, c, row bounds) and of the optimal solution timed with the
real overheads.  Identical lines = the same plans, models and plan ids.

    cd TREE && PYTHONPATH=$PWD python benchmarks/identity/exposure_menu_identity.py > out.txt
"""
import hashlib, json, numpy as np
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.sky.skymap import read_skymap
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.planner import run_scheduler, build_plan
from mushrooms.scheduler_core.schedulers.detection import stage as ds
from mushrooms.scheduler_core.schedulers.slots.schedule import slot_rows, slot_portfolio, time_slot_plan
from mushrooms.scheduler_core.schedulers.slots.model import slot_instance
from mushrooms.scheduler_core.schedulers.blocks.schedule import shortlist_footprints
from mushrooms.scheduler_core.sky.cells import merge_cells
from mushrooms.scheduler_core.source.kilonova import load_kilonova
from mushrooms.scheduler_core.schedulers.milp.solvers import solve_milp
for path in ("tests/data/skymaps/MS220722v_bayestar.multiorder.fits", "/work/shared/data/skymaps/simulated/bns_o3/1.fits"):
    sm = read_skymap(path, nside=64)
    cfg = PlanningConfig(nside=64)
    problem = prepare_problem(sm, cfg, sm.event_time)
    cov = run_scheduler(problem, "greedy")
    plan = build_plan(problem, cov, sm, "greedy")
    doc = json.dumps([(o.field_id, o.filter, round(o.start, 6), o.exposure_s) for o in plan.observations])
    rows = slot_rows(problem, np.unique([o.field_id for o in cov.observations]))
    fp = shortlist_footprints(problem.footprints, rows); cells = merge_cells(fp, problem.prob)
    g = slot_portfolio(problem, rows)[0]
    inst = slot_instance(problem, rows, g, cells=cells)
    reach = ds.pair_reach(problem, inst, load_kilonova("conservative"), sm.event_time)
    lev = ds.distance_levels(sm, np.unique(fp.indices), float(reach.max()), 8)
    W = ds.level_weights(sm, fp, cells, lev)
    dm = ds.build_detection_model(inst, W, ds.pair_levels(reach, lev), 0.0, 0.05, coverage_floor=0.05)
    m = dm.model.milp
    h = hashlib.sha256(m.A.toarray().tobytes() + m.c.tobytes() + m.row_lo.tobytes() + m.row_hi.tobytes()).hexdigest()[:16]
    res = solve_milp(m, "highs", 30.0, 0.0, 1)
    obs, dropped, _ = time_slot_plan(problem, dm.model, res.x)
    t = hashlib.sha256(json.dumps([(o.field_id, o.filter, round(o.start, 6), o.exposure_s) for o in obs]).encode()).hexdigest()[:16]
    print(path.split("/")[-1], plan.plan_id, hashlib.sha256(doc.encode()).hexdigest()[:16], "model", h, res.status, "timed", t, len(obs))
