import sys, time
from mushrooms.scheduler_core import PlanningConfig, read_skymap, prepare_problem, run_scheduler
cfg = PlanningConfig(filters=("g","r","g"), exposure_s=180.0, threads=1)
for m in sys.argv[1:]:
    sky = read_skymap(m, nside=cfg.nside)
    p = prepare_problem(sky, cfg, sky.event_time)
    t = time.perf_counter(); r = run_scheduler(p, "greedy"); dt = time.perf_counter() - t
    cov = p.footprints.coverage({o.field_id for o in r.observations}, p.prob)
    print(m.split('/')[-1], len(p.field_ids), "fields", len(r.observations), "exposures", "coverage %.4f" % cov, "greedy %.2f s" % dt)
