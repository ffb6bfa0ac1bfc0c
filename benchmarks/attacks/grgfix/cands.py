import sys, dataclasses
from mushrooms.scheduler_core import PlanningConfig, read_skymap, prepare_problem, run_scheduler
from mushrooms.scheduler_core.schedulers.gain import published_coverage
from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverages_as_executed, _keyed
cfg = PlanningConfig(filters=("g","r","g"), exposure_s=180.0, threads=1, objective="coverage")
for m in sys.argv[1:]:
    sky = read_skymap(m, nside=cfg.nside)
    p = prepare_problem(sky, cfg, sky.event_time)
    r = run_scheduler(p, "hybrid")
    print(m.split('/')[-1][:28], "choice", r.portfolio_choice)
    from mushrooms.scheduler_core.schedulers.portfolio.portfolio import greedy_stage, slots_stage
    g = greedy_stage(p, None, {}, 10.0); s = slots_stage(p, None, {"greedy": g}, 10.0)
    for name, res in (("greedy", g), ("slots", s)):
        key, pair, whole = keyed_coverages_as_executed(p, res, {})
        # strict Q21
        from mushrooms.scheduler_core.schedulers.as_executed import execute_plan_queues, sequence_coverage
        n = {}
        for o in res.observations: n[o.field_id] = n.get(o.field_id, 0) + 1
        print(f"  {name}: planned {published_coverage(p, res):.4f} C_exec {pair:.4f} C_seq' {whole:.4f} cut fields {sum(v == 2 for v in n.values())}/{len(n)}")
