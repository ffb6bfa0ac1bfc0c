"""Reproduction: does a plan depend on how fast the machine runs?  One input planned twice, once as if ten times slower.

``make_plan`` on the test map (MS220722v, nside 64, a small budget: time_limit_s 3, detection 1, bound 1), once
as it is and once with ``time.perf_counter`` running ten times faster (every wall-clock reading says ten times
the time went by: a machine ten times slower, or loaded).  Prints each document's sha256 without its timing
fields (created, metrics.runtime_s, metrics.latency_s) and whether they are equal.

    python benchmarks/attacks/slow_clock_plans.py [--deterministic true|false]

Without ``--deterministic`` the configuration is the checkout's default (a checkout without the key: the wall
budget).  Runs on any checkout (it strips the timing fields itself).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

TIMING = ("created", "metrics.runtime_s", "metrics.latency_s")


def digest(doc: dict) -> str:
    """sha256 of the document without its timing fields."""
    doc = json.loads(json.dumps(doc))
    for name in TIMING:
        *path, key = name.split(".")
        where = doc
        for part in path:
            where = where.get(part) or {}
        where.pop(key, None)
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--deterministic", choices=("true", "false"))
    args = parser.parse_args()
    from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap

    keys = dict(nside=64, milp_backend="highs", time_limit_s=3.0, detection_time_limit_s=1.0, bound_time_limit_s=1.0)
    if args.deterministic:
        keys["deterministic"] = args.deterministic == "true"
    cfg = PlanningConfig(**keys)
    sm = read_skymap(ROOT / "tests" / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits", nside=64)
    docs = []
    for factor in (1.0, 10.0):
        real = time.perf_counter
        t0 = real()
        time.perf_counter = lambda: t0 + factor * (real() - t0)
        try:
            doc = make_plan(sm, cfg).to_document()
        finally:
            time.perf_counter = real
        m = doc["metrics"]
        print(f"wall clock x{factor:g}: sha256 {digest(doc)}  runtime_s {m['runtime_s']}  {m['solver']} "
              f"{m['status']}  coverage {m['coverage']}  expected {m.get('expected_detections')}  "
              f"budget {json.dumps(m.get('budget'))}", flush=True)
        docs.append(doc)
    same = digest(docs[0]) == digest(docs[1])
    print("identical without timing fields" if same else "DIFFERENT documents")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
