"""Issue 31 part B diagnosis: per map, the menu detection stage's grids at a short and a long budget."""
import dataclasses, json, sys, time
import numpy as np
sys.path.insert(0, "/work/main/benchmarks"); import mushrooms; print("code:", mushrooms.__file__)
from exposure_menu import scaled, MAPS
from mushrooms.scheduler_core.config import PlanningConfig
from mushrooms.scheduler_core.planner import run_scheduler
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.schedulers import detection_slots as ds
from mushrooms.scheduler_core.sky.skymap import read_skymap

LOG = []
from mushrooms.scheduler_core.schedulers import slot_schedule as ss
_solve, _ms, _mm = ds.solve_milp, ss.map_start, ds.map_start_menu
def solve(milp, backend, limit, gap, threads, stop, start=None):
    t = time.perf_counter()
    res = _solve(milp, backend, limit, gap, threads, stop, start=start)
    rec = {"n_vars": milp.n_vars, "n_rows": milp.n_rows, "limit_s": round(limit, 2), "took_s": round(time.perf_counter() - t, 2),
           "status": res.status, "obj": None if not res.has_solution else round(float(res.objective), 4),
           "bound": None if res.bound is None else round(float(res.bound), 4)}
    if start is not None:
        ax = milp.A @ start
        feas = bool(np.all(ax >= milp.row_lo - 1e-6) and np.all(ax <= milp.row_hi + 1e-6))
        rec.update(start_obj=round(float(milp.c @ start), 4), start_feasible=feas)
    else:
        rec["start"] = None
    LOG.append(rec)
    return res
def ms(inst, start, *a):
    p = (_mm if a else _ms)(inst, start, *a)
    LOG.append({"start_fields": len(start), "placed": int(p.size)})
    return p
ds.solve_milp, ss.map_start = solve, ms
ds.map_start_menu = lambda inst, start, exp: ms(inst, start, exp)

name, scale = sys.argv[1], float(sys.argv[2])
budgets = [float(b) for b in sys.argv[3].split(",")]
cfg = PlanningConfig(nside=128, threads=1)
sm = read_skymap(MAPS / name, nside=128)
if scale != 1:
    sm = scaled(sm, scale)
problem = prepare_problem(sm, cfg, sm.event_time)
cov = run_scheduler(dataclasses.replace(problem, config=dataclasses.replace(cfg, objective="coverage",
                    time_limit_s=cfg.time_limit_s - cfg.detection_time_limit_s)), "hybrid")
print(f"## {name} x{scale:g} distmean {float(sm.distmean):.0f} Mpc; coverage plan {len({o.field_id for o in cov.observations})} fields grid {cov.grid}")
menu = tuple(float(x) for x in (sys.argv[4] if len(sys.argv) > 4 else "30,60,120,300,600").split(","))
for b in budgets:
    for tag, m in (("fixed", ()), ("menu", menu)):
        p = dataclasses.replace(problem, config=dataclasses.replace(cfg, exposure_menu_s=m, time_limit_s=max(14.0, b + 1),
                                                                    detection_time_limit_s=b))
        LOG.clear()
        t = time.perf_counter()
        det = ds.detection_stage(p, sm, cov, time_limit_s=b)
        r = det.detection
        print(f"[{tag} budget {b:g}s wall {time.perf_counter()-t:.1f}s] choice={r.choice} E_cov={r.expected_detections_coverage:.4f} floor={r.coverage_floor:.4f}")
        for g in r.grids:
            g = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in g.items()}
            print("   grid", json.dumps(g))
        for l in LOG:
            print("   milp", json.dumps(l))
    sys.stdout.flush()
