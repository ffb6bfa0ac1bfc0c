"""How many re-plans of random executed subsets of a g-r-g plan the checker refuses (F3, F9).

    python benchmarks/execution/sequence_replans.py [N]

Per map (MS220722v from tests/data, G483432 from the shared public maps) and per pair
separation (0: one night; 4000 s: little room beyond a g-r-g's two cadences): a greedy g-r-g
plan at 180 s, then N re-plans from a random point of it with a random 90 % of the exposures
before that point done (seeded), each through ``plan_remaining`` and ``check_plan`` with the
executed record (``mushrooms check --executed``).  Prints the count refused.
"""

from __future__ import annotations

import random
import sys
from pathlib import Path

from mushrooms.scheduler_core import PlanningConfig, check_plan, make_plan, read_skymap
from mushrooms.scheduler_core.errors import PlanCheckError
from mushrooms.scheduler_core.executed import ExecutedExposure
from mushrooms.scheduler_core.replan import plan_remaining

MAPS = (Path(__file__).resolve().parents[2] / "tests" / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits",
        Path("/work/shared/data/skymaps/public/G483432_bayestar.multiorder.fits"))


def refused(path: Path, pair_max_s: float, n: int) -> int:
    cfg = PlanningConfig(solver="greedy", filters=("g", "r", "g"), exposure_s=180.0, pair_max_s=pair_max_s)
    sky = read_skymap(path, nside=cfg.nside)
    plan = make_plan(sky, cfg)
    obs = sorted(plan.observations, key=lambda o: o.start)
    rng, count = random.Random(7), 0
    for _ in range(n):
        cut = rng.randrange(1, len(obs))
        done = [o for o in obs[:cut] if rng.random() < 0.9]
        executed = [ExecutedExposure(o.field_id, o.filter, plan.absolute_time(o.start), o.exposure_s, 1.0,
                                     "processed") for o in done]
        try:
            replan = plan_remaining(sky, cfg, plan.absolute_time(obs[cut - 1].end), executed)
            count += not check_plan(replan, sky, cfg, executed=executed).ok
        except PlanCheckError:
            count += 1
    return count


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    for path in MAPS:
        for pair_max_s in (0.0, 4000.0):
            print(f"{path.name:<40} pair_max_s {pair_max_s:>6.0f}  re-plans {n}  refused {refused(path, pair_max_s, n)}",
                  flush=True)
