"""Models and plans identical across a refactor of the MILP builders: hash every model, print every plan.

Run in two trees (before and after) and diff the outputs::

    PYTHONPATH=$PWD python benchmarks/identity/model_identity.py MAP [MAP ...] > out.txt

For each map (FITS, or a notice JSON with an embedded map) and each solver
(greedy, slots and blocks under the coverage objective, slots under the
detection objective) it prints the SHA-256 of every MILP handed to HiGHS
(matrix, row and column bounds, objective, integrality) and the plan's
fields, filters and start times; the exact model (C0-C6) is built on a
reduced instance of each map (``evaluation.reduced``) and hashed too.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from mushrooms.scheduler_core import PlanningConfig, make_plan, prepare_problem, read_skymap
from mushrooms.scheduler_core.schedulers.milp import solvers

SEEN: list[str] = []
#: solver/objective pairs run (``$RUNS``, e.g. ``blocks/coverage``) and their budget (``$TIME_LIMIT_S``):
#: a plan is the same in two trees only when no solve stops at its time limit
RUNS = [tuple(r.split("/")) for r in os.environ.get(
    "RUNS", "greedy/coverage slots/coverage blocks/coverage slots/detection").split()]
TIME_LIMIT_S = float(os.environ.get("TIME_LIMIT_S", "60"))


def model_hash(model) -> str:
    A = sp.csr_matrix(model.A, copy=True)
    A.sum_duplicates()
    A.sort_indices()
    h = hashlib.sha256()
    for arr in (A.indptr, A.indices, A.data, model.row_lo, model.row_hi, model.c, model.col_lo, model.col_hi,
                model.integer):
        h.update(np.ascontiguousarray(np.asarray(arr)).tobytes())
    h.update(str(A.shape).encode())
    return h.hexdigest()[:16]


_orig = solvers._solve_highs


def _recording(model, *args, **kwargs):
    SEEN.append(f"{model_hash(model)} {model.n_rows}x{model.n_vars}")
    return _orig(model, *args, **kwargs)


solvers._solve_highs = _recording


def load(path: str, nside: int):
    if path.endswith(".json"):
        data = base64.b64decode(json.loads(Path(path).read_text())["event"]["skymap"])
        return read_skymap(data, nside=nside)
    return read_skymap(path, nside=nside)


def main() -> None:
    nside = 64
    for path in sys.argv[1:]:
        skymap = load(path, nside)
        print(f"# {Path(path).name}")
        for solver, objective in RUNS:
            cfg = PlanningConfig(solver=solver, objective=objective, nside=nside, time_limit_s=TIME_LIMIT_S,
                                 detection_time_limit_s=30, bound_time_limit_s=0, threads=1, mip_gap=1e-4)
            SEEN.clear()
            plan = make_plan(skymap, cfg)
            obs = [(o.field_id, o.filter, o.start, o.block)
                   for o in plan.observations]
            print(f"{solver}/{objective}: status {plan.metrics.status} coverage {plan.metrics.coverage} "
                  f"n_obs {len(obs)} plan {hashlib.sha256(repr(obs).encode()).hexdigest()[:16]}")
            for s in SEEN:
                print(f"    model {s}")
        from mushrooms.evaluation.reduced import reduced_problem
        from mushrooms.scheduler_core.schedulers.portfolio.continuous import build_exact_model
        cfg = PlanningConfig(solver="greedy", nside=nside)
        small = reduced_problem(prepare_problem(skymap, cfg, skymap.event_time), 8)
        em = build_exact_model(small)
        print(f"exact C0-C6 (8 fields): model {model_hash(em.milp)} {em.milp.n_rows}x{em.milp.n_vars}")


if __name__ == "__main__":
    main()
