"""Does the plan checker cost less than the greedy scheduler whose plans it checks?

For each sky map: prepare the problem once, then time ``greedy_schedule`` and
``check_plan`` on its plan (median of ``--repeat`` runs each, interleaved so
that both see the same machine load).  The checker should not
cost more than the greedy scheduler.

Usage::

    nice -n 5 .venv/bin/python benchmarks/speed/checker_timing.py SKYMAP [SKYMAP ...] [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from astropy.time import Time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("skymaps", nargs="+", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--start", help="horizon start (ISO UTC) for maps without an event time",
                    default="2020-01-29T12:00:00")
    args = ap.parse_args(argv)

    from mushrooms.offline import configure_astropy_offline
    from mushrooms.scheduler_core import PlanningConfig, check_plan, read_skymap
    from mushrooms.scheduler_core.schedulers.greedy.schedule import greedy_schedule
    from mushrooms.scheduler_core.planner import build_plan
    from mushrooms.scheduler_core.prepare import prepare_problem

    configure_astropy_offline()
    cfg = PlanningConfig(solver="greedy")
    ratios = []
    print(f"{'map':48s} {'exposures':>9s} {'greedy_s':>9s} {'checker_s':>9s} {'ratio':>6s}  verdict")
    for path in args.skymaps:
        sky = read_skymap(path, nside=cfg.nside)
        problem = prepare_problem(sky, cfg, sky.event_time or Time(args.start, scale="utc"))
        plan = build_plan(problem, greedy_schedule(problem), sky, "greedy")
        check_plan(plan, sky, cfg)  # warm the caches (data files, astropy) as a running service has them
        t_greedy, t_check = [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            greedy_schedule(problem)
            t_greedy.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            report = check_plan(plan, sky, cfg)
            t_check.append(time.perf_counter() - t0)
        g, c = statistics.median(t_greedy), statistics.median(t_check)
        ratios.append(c / g)
        print(f"{path.name:48s} {len(plan.observations):9d} {g:9.3f} {c:9.3f} {c / g:6.2f}  "
              f"{'ok' if report.ok else report.problems[0]}")
    print(f"median checker/greedy ratio over {len(ratios)} maps: {statistics.median(ratios):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
