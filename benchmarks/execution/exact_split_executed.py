"""The optimiser's loss as planned and as executed: greedy, the hybrid and the exact model on reduced instances.

Usage::

    python benchmarks/execution/exact_split_executed.py [--k 20] [--exact-limit 30] [--plan-limit 10]
                                              [--cadence-margins 120 180] MAP [MAP ...]

For each map's reduced instance (the top ``k`` pairable fields,
:func:`mushrooms.evaluation.reduced.reduced_problem`; the coverage objective,
``threads = 1``, ``min_gain = 0``, as ``exact_split.py``) it prints the
coverage of greedy, the hybrid and the exact model (C0-C6, started from the
greedy and hybrid plans) as planned and as ZTF's scheduler executes the
plan's queues (Q14, ``metrics.coverage_as_executed``), then the exact model
solved with the cadence widened by each ``--cadence-margins`` value (s): a
plan of that model keeps every pair that much further apart than the
cadence, scored on the real problem.  Not a test: nothing here asserts.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path


def measure(path: Path, k: int, exact_limit: float, plan_limit: float, margins: list[float]) -> list[str]:
    """The lines of one map: each plan's coverage as planned and as executed."""
    from astropy.time import Time

    from mushrooms.evaluation.exact import solve_exact
    from mushrooms.evaluation.reduced import reduced_problem
    from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
    from mushrooms.scheduler_core.planner import run_scheduler
    from mushrooms.scheduler_core.schedulers.as_executed import keyed_coverage_as_executed

    cfg = PlanningConfig(objective="coverage", threads=1, time_limit_s=plan_limit, milp_backend="highs",
                         min_gain=0.0, min_coverage=0.0)
    sm = read_skymap(path, nside=cfg.nside)
    problem = reduced_problem(prepare_problem(sm, cfg, Time(sm.event_time, scale="utc")), k)

    def row(name: str, result) -> str:
        planned = problem.footprints.coverage({o.field_id for o in result.observations}, problem.prob)
        executed = keyed_coverage_as_executed(problem, result)[1]
        return f"  {name:34s} {result.status:>16s} planned {planned:.4f} executed {executed:.4f}"

    greedy = run_scheduler(problem, "greedy")
    hybrid = run_scheduler(problem, "hybrid")
    out = [f"{path} k={len(problem.field_ids)}", row("greedy", greedy),
           row(f"hybrid ({hybrid.portfolio_choice})", hybrid)]
    exact = solve_exact(problem, time_limit_s=exact_limit, threads=1,
                        starts=(greedy.observations, hybrid.observations))
    out.append(row("exact, the cadence", exact.result))
    for margin in margins:
        wide = dataclasses.replace(problem, config=dataclasses.replace(cfg, cadence_s=cfg.cadence_s + margin))
        ex = solve_exact(wide, time_limit_s=exact_limit, threads=1, starts=(greedy.observations,))
        out.append(row(f"exact, the cadence + {margin:g} s", ex.result))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+", type=Path)
    ap.add_argument("--k", type=int, default=20, help="fields per reduced instance")
    ap.add_argument("--exact-limit", type=float, default=30.0, help="time limit (s) of each exact solve")
    ap.add_argument("--plan-limit", type=float, default=10.0, help="hybrid's time_limit_s (s)")
    ap.add_argument("--cadence-margins", type=float, nargs="*", default=[120.0, 180.0],
                    help="extra separations (s) the exact model is also solved with")
    a = ap.parse_args(argv)
    for path in a.maps:
        print("\n".join(measure(path, a.k, a.exact_limit, a.plan_limit, a.cadence_margins)), flush=True)
    print(f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
