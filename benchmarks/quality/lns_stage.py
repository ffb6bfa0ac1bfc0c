"""The hybrid with and without its LNS stage , per map: each stage's published coverage.

Usage::

    python benchmarks/quality/lns_stage.py [--without-lns] [--lns-share F] [--lns-idle S] [--time-limit 10] MAP ...

Coverage objective, ``threads = 1``, the default ``min_gain``; ``MAP`` relative to the shared sky-map
folder or a path.  Printed per map: the winning stage, every stage's published coverage, the wall time
(s, the bound's included), the certified bound, the rule problems of the plan (0), and, when the LNS
wins, after how many slices (and seconds) it improved.  With ``--lns-idle S`` the LNS stops after ``S``
seconds without a gain instead of :data:`~mushrooms.scheduler_core.schedulers.portfolio.lns.MAX_IDLE_S`, and every
map's line shows the LNS's gains, ``(s, coverage)``, and each stage's wall time, whether it wins or not: run
with a large ``S`` it is the trajectory from which a shorter idle stop's plan is read off
(``benchmarks/quality/lns_idle_replay.py``).  Not a test: nothing here asserts.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SHARED = next((p for p in (ROOT.parent / "shared" / "data" / "skymaps", Path("/work/shared/data/skymaps"))
               if p.is_dir()), Path("/work/shared/data/skymaps"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+")
    ap.add_argument("--without-lns", action="store_true", help="the hybrid of before the LNS stage")
    ap.add_argument("--lns-share", type=float, default=None, help="share of time_limit_s the slots leave to the LNS (default 0, as shipped)")
    ap.add_argument("--lns-idle", type=float, default=None, help="seconds without a gain that end the LNS")
    ap.add_argument("--time-limit", type=float, default=10.0, help="time_limit_s (the coverage hybrid's 10 s)")
    args = ap.parse_args(argv)

    from astropy.time import Time

    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import run_scheduler
    from mushrooms.scheduler_core.schedulers.portfolio import portfolio as pf
    from mushrooms.scheduler_core.schedulers.portfolio.lns import plan_rule_problems

    hybrid_stages = pf.hybrid.stages
    if args.without_lns:
        hybrid_stages = tuple(s for s in hybrid_stages if s.name != "lns")
    share = args.lns_share or 0.0
    if share:
        def slots_leaving_share(problem, should_stop, earlier, left_s):
            return pf.slots_stage(problem, should_stop, earlier, left_s - share * problem.config.time_limit_s)

        hybrid_stages = tuple(dataclasses.replace(s, run=slots_leaving_share) if s.name == "slots" else s for s in hybrid_stages)
    lns_runs: dict = {}
    if args.lns_idle is not None:
        def lns_idle(problem, should_stop, earlier, left_s):
            lns_runs["last"] = pf.lns_stage(problem, should_stop, earlier, left_s, max_idle_s=args.lns_idle)
            return lns_runs["last"]

        hybrid_stages = tuple(dataclasses.replace(s, run=lns_idle) if s.name == "lns" else s for s in hybrid_stages)
    pf.register("hybrid", pf.with_upper_bound(dataclasses.replace(pf.hybrid, stages=hybrid_stages)))
    label = "without-lns" if args.without_lns else f"lns-share={share:g}"
    if args.lns_idle is not None:
        label += f",idle={args.lns_idle:g}"
    for m in args.maps:
        path = Path(m) if Path(m).exists() else SHARED / m
        cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=args.time_limit, milp_backend="highs")
        sm = read_skymap(path, nside=cfg.nside)
        problem = prepare_problem(sm, cfg, Time(sm.event_time, scale="utc"))
        t = time.perf_counter()
        lns_runs.clear()
        r = run_scheduler(problem, "hybrid")
        wall = time.perf_counter() - t
        stages = " ".join(f"{e.name}={e.coverage:.4f}" for e in r.portfolio)
        lns = r.details if r.portfolio_choice == "lns" else {}
        when = f" improved_at={lns.get('improved_at')} s={lns.get('elapsed_at')}" if lns else ""
        if args.lns_idle is not None:
            d = lns_runs["last"].details if "last" in lns_runs else {}
            gains = list(zip(d.get("elapsed_at", []), d.get("coverage_at", [])))
            when = (f" lns_seed={d.get('seed_coverage', float('nan')):.6f} lns_s={lns_runs['last'].runtime_s:.2f}"
                    if d else " lns_seed=nan lns_s=0") + f" gains={gains} times={r.details.get('stage_times_s')}"
        print(f"{label} {m} choice={r.portfolio_choice} {stages} wall={wall:.1f} bound={r.upper_bound.value:.4f} "
              f"rules={len(plan_rule_problems(problem, r.observations))}{when}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
