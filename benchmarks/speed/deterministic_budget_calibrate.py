"""The work clock's rates (``scheduler_core/budget.py``, A2-A3) against this machine's CPU time.

Per map, the default optimisation (``planner.optimise``) runs once on the work clock; every step the clock charges
(a HiGHS solve, greedy, the executor, a plan's scoring, a slot solution's timing, a grid's model, the detection
model's reaches, an LNS slice's model) is timed in CPU seconds of this thread (``time.thread_time``: what the step
takes on a quiet machine, about the same under load) beside what the clock charged for it.  Printed per step: how
many, the CPU seconds and the work seconds charged (sums, and their ratio), and a least-squares fit of CPU seconds
on (1, items) per Python step and on (1, nnz, LP iterations x (rows + columns), checks) for HiGHS; the HiGHS solves'
iterations per limit check; per map the optimisation's whole CPU time against the work spent.

    python benchmarks/speed/deterministic_budget_calibrate.py [MAP ...]   (default: six shared maps)
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
#: ../shared/data/skymaps from the checkout (or from a worktree one level deeper)
SKYMAPS = next((p / "shared" / "data" / "skymaps" for p in ROOT.parents if (p / "shared" / "data").is_dir()),
               ROOT.parent / "shared" / "data" / "skymaps")
DEFAULT_MAPS = ["public/G476954_bayestar.fits.gz", "public/S191216ap_bayestar.multiorder.fits",
                "simulated/bns_o3/11.fits", "public/M403699_bayestar.multiorder.fits", "simulated/bns_o3/18.fits",
                "public/S230627c_Bilby.multiorder.fits"]

#: step -> (function's module, name, items of its call)
WRAPPED = {
    "greedy": ("mushrooms.scheduler_core.schedulers.greedy.schedule", "greedy_schedule", lambda a, r: len(a[0].field_ids)),
    "execute": ("mushrooms.scheduler_core.schedulers.as_executed", "keyed_coverage_as_executed",
                lambda a, r: len(a[1].observations)),
    "score": ("mushrooms.scheduler_core.schedulers.detection.stage", "plan_expected_detections",
              lambda a, r: len(a[2])),
    "timing": ("mushrooms.scheduler_core.schedulers.slots.schedule", "time_slot_plan", lambda a, r: len(r[0])),
    "grid": ("mushrooms.scheduler_core.schedulers.slots.model", "build_slot_model", lambda a, r: r.instance.n_pairs),
    "reach": ("mushrooms.scheduler_core.schedulers.detection.model", "pair_reach", lambda a, r: len(r)),
    "slice": ("mushrooms.scheduler_core.schedulers.portfolio.lns", "resolve_slice", None),
    "solve": ("mushrooms.scheduler_core.schedulers.milp.solvers", "solve_milp", None),
}


def nominal(name: str, size) -> float | None:
    """The work seconds the clock charges a step of this size (A2 for a solve, A3 for the others)."""
    from mushrooms.scheduler_core import budget

    if size is None:
        return None
    if name == "solve":
        return budget.highs_work(*size) / budget.TICKS_PER_S  # (nnz, rows + columns, checks, iterations)
    base, per_item = budget.STEP_COSTS[name]
    return base + per_item * size


def instrument(rows: list) -> None:
    """Wrap the steps (every module holding them) to append (step, cpu s, work s, items) to ``rows``.

    An execute call answered from a memo costs no work and is not a row; an LNS slice's items are its model's
    nonzeros (a slice that built no model, none)."""
    import importlib

    from mushrooms.scheduler_core import budget

    solves: list = []
    original_solve_charge = budget.SolveWork.charge

    def solve_charge(self, gurobi_work=None, iterations=0):
        original_solve_charge(self, gurobi_work, iterations)
        solves.append((self.nonzeros, self.size, self.checks, self.iterations))

    budget.SolveWork.charge = solve_charge
    for name, (module, attr, items) in WRAPPED.items():
        fn = getattr(importlib.import_module(module), attr)

        def wrapped(*a, _fn=fn, _name=name, _items=items, **k):
            cpu0, n0, r0 = time.thread_time(), len(solves), len(rows)
            r = _fn(*a, **k)
            cpu = time.thread_time() - cpu0 - sum(x[1] for x in rows[r0:])  # inner steps are their own rows
            if _items is not None:
                size = _items(a, r)
            elif len(solves) > n0:
                size = solves[-1] if _name == "solve" else solves[-1][0]
            else:
                size = None
            if not (_name == "execute" and cpu < 1e-3):  # a memo's answer
                rows.append((_name, cpu, nominal(_name, size), size))
            return r

        for mod in list(sys.modules.values()):
            if getattr(mod, "__name__", "").startswith("mushrooms") and getattr(mod, attr, None) is fn:
                setattr(mod, attr, wrapped)


def fit(rows: list, name: str) -> str:
    """Least squares of CPU seconds on the step's items (HiGHS: on nnz and nnz x checks)."""
    sel = [r for r in rows if r[0] == name and r[3] is not None]
    if len(sel) < 3:
        return "too few to fit"
    y = np.array([r[1] for r in sel])
    if name == "solve":  # (nnz, rows + columns, checks, iterations)
        X = np.array([[1.0, r[3][0], r[3][3] * r[3][1], r[3][2]] for r in sel])
    else:
        X = np.array([[1.0, float(r[3])] for r in sel])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return "fit " + " ".join(f"{c:.3g}" for c in coef)


def main(paths: list[Path]) -> None:
    import os

    from mushrooms.scheduler_core import PlanningConfig, read_skymap
    from mushrooms.scheduler_core.planner import optimise
    from mushrooms.scheduler_core.prepare import prepare_problem

    rows: list = []
    instrument(rows)
    cfg = PlanningConfig(milp_backend="highs", deterministic=True)
    per_map = []
    for path in paths:
        sm = read_skymap(path, nside=cfg.nside)
        problem = prepare_problem(sm, cfg, sm.event_time)
        cpu0, wall0 = time.thread_time(), time.perf_counter()
        result = optimise(problem, sm, cfg.solver)
        per_map.append((path.name, time.thread_time() - cpu0, time.perf_counter() - wall0,
                        result.details["budget"]["spent"], os.getloadavg()[0]))
        print(f"{path.name}: cpu {per_map[-1][1]:.2f} s, wall {per_map[-1][2]:.2f} s, work {per_map[-1][3]:.2f} "
              f"work_s (load {per_map[-1][4]:.1f})", flush=True)
    print("\nstep      n   cpu_s   work_s  work/cpu  per-call fit (cpu s = a + b items; solve: a + b nnz + c iterations "
          "(rows + columns) + d checks)")
    by = collections.defaultdict(list)
    for r in rows:
        by[r[0]].append(r)
    for name, rs in by.items():
        cpu, work = sum(r[1] for r in rs), sum(r[2] or 0.0 for r in rs)
        print(f"{name:8s} {len(rs):4d} {cpu:7.2f} {work:8.2f} {work / max(cpu, 1e-9):8.2f}  {fit(rows, name)}")
    per_check = [r[3][3] / r[3][2] for r in rows if r[0] == "solve" and r[3] and r[3][2] >= 10]
    if per_check:
        print(f"HiGHS LP iterations per limit check (the {len(per_check)} solves with 10 checks or more): "
              f"percentiles 10/50/90 " + "/".join(f"{q:.0f}" for q in np.percentile(per_check, [10, 50, 90])))
    cpu, work = sum(m[1] for m in per_map), sum(m[3] for m in per_map)
    print(f"\nwhole optimisation, {len(per_map)} maps: cpu {cpu:.2f} s, work {work:.2f} work_s, work/cpu {work / cpu:.2f}; "
          f"per map work/cpu: " + ", ".join(f"{m[3] / m[1]:.2f}" for m in per_map))


if __name__ == "__main__":
    given = [Path(p) for p in sys.argv[1:]]
    main(given or [SKYMAPS / m for m in DEFAULT_MAPS])
