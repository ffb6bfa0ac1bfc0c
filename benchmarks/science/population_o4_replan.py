#!/usr/bin/env python3
"""The frozen release's plans again, for the matched-time table (issue 55 item 2): the study records keep metrics only.

The release run (``benchmarks/results/science/population_o4/study/results.jsonl.gz``) stores each (map, row)'s
metrics, not its plan, so the coverage a row had reached after some open-shutter time cannot be read from it.
This script plans the rows again **with the frozen code** (run it with ``PYTHONPATH`` on a tree of the commit
that planned the records, e.g. ``git archive af0ff7d``): the study's own path, :func:`bench_map` on one map and
one row under the run's ``config.toml`` on the deterministic (work) budget, so a plan depends on its inputs
only.  gwemopt is never run: its rows read a copy of the run's gwemopt cache with ``gwemopt_cache_only``.

To save CPU the bench's scorer is replaced by the part of it that pins a plan down (the executed queue set's
coverage and open-shutter seconds, the pair-rule planned coverage, the exposure count, the coverage the plan reports);
every value is compared with the frozen record, and a plan that differs in any is marked ``reproduced: false``
(the matched-time table leaves it out and says how many).

Output: one JSON line per (map, row), ``map``, ``solver``, ``reproduced``, ``frozen`` / ``again`` (the values
compared) and ``plan`` (the plan document), gzipped.

    PYTHONPATH=/tmp/frozen nice -n 19 /work/main/.venv/bin/python benchmarks/science/population_o4_replan.py \\
        --records benchmarks/results/science/population_o4/study/results.jsonl.gz \\
        --config benchmarks/results/science/population_o4/study/config.toml --gwemopt-cache /tmp/gwemopt-cache \\
        --out /tmp/plans.jsonl.gz [--rows service,service-grg,greedy,gwemopt-o4,gwemopt-skyportal] [--maps-root R]
"""

from __future__ import annotations

import argparse
import dataclasses
import gzip
import json
import sys
import time
from pathlib import Path

#: The values compared with the frozen record (the record's ``row`` keys).
COMPARED = ("coverage_reported", "coverage_as_executed", "open_shutter_executed_s", "coverage_pairs", "open_shutter_s",
            "n_exposures")
#: The rows the matched-time table needs: the service's three and the two gwemopt configurations ZTF ran.
ROWS = ("service", "service-grg", "greedy", "gwemopt-o4", "gwemopt-skyportal")


def light_scorer(captured: dict):
    """A stand-in for the bench's ``score_plan``: keeps the plan, returns the cells of :data:`COMPARED`."""
    from mushrooms.evaluation.bench.rows import fmt
    from mushrooms.evaluation.bench.scoring import _under_config, execution_cells_under, pair_cells

    def score(plan, skymap, settings, footprints, injections, lightcurves, merger_time):
        captured["plan"] = _under_config(plan, settings.config)  # a baseline's plan with the row's filters, cadence
        out = dict(coverage_reported=fmt(float(plan.metrics.coverage)), n_exposures=len(plan.observations))
        out.update(execution_cells_under(plan, settings.config, footprints, skymap.prob))
        out.update(pair_cells(plan, settings.config, footprints, skymap.prob))
        return out, {}

    return score


def skip_scoring_inputs() -> None:
    """What only the skipped scoring uses, not made: the late starts' runs and the map's kilonova injections
    (``scene.injections`` feeds ``score_plan`` alone; the planner draws nothing from it)."""
    import functools

    from mushrooms.evaluation import efficiency, queue_sim

    queue_sim.execution_cells = functools.partial(queue_sim.execution_cells, late_starts_s=())
    efficiency.draw_injections = lambda *a, **k: None


def same(a, b, tol: float = 1e-6) -> bool:
    """Equal as numbers (within ``tol``), else as text."""
    try:
        return abs(float(a) - float(b)) <= tol
    except (TypeError, ValueError):
        return str(a) == str(b)


def settings_of(config_path: Path, gwemopt_cache: Path):
    """The study's bench settings (``mushrooms study``'s: ``bench_settings`` then ``study_bench_settings``),
    gwemopt from the cache copy only."""
    from mushrooms.evaluation.study.run import study_bench_settings
    from mushrooms.tool.bench import bench_settings
    from mushrooms.tool.config import load_config

    args = argparse.Namespace(solvers="service", injections=10000, start=None, arm=None, jobs=1)
    s = study_bench_settings(bench_settings(args, load_config(config_path)))
    return dataclasses.replace(s, bench=dataclasses.replace(s.bench, gwemopt_cache_dir=str(gwemopt_cache),
                                                            gwemopt_cache_only=True))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=Path, required=True)
    ap.add_argument("--config", type=Path, required=True)
    ap.add_argument("--gwemopt-cache", type=Path, required=True, help="a COPY of the run's gwemopt cache")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--rows", default=",".join(ROWS))
    ap.add_argument("--reverse", action="store_true", help="the records in reverse order (a second process)")
    ap.add_argument("--maps-root", type=Path, help="replace the records' map directory prefix "
                    "/work/population_o4_real by this one")
    args = ap.parse_args()
    from mushrooms.evaluation.bench import per_map
    from mushrooms.evaluation.bench.run import worker_init

    worker_init()
    rows = [r for r in args.rows.split(",") if r]
    settings = settings_of(args.config, args.gwemopt_cache)
    records = [json.loads(line) for line in gzip.open(args.records, "rt")]
    done = set()
    if args.out.exists():
        done = {(d["map"], d["solver"]) for d in map(json.loads, gzip.open(args.out, "rt"))}
    captured: dict = {}
    per_map.score_plan = light_scorer(captured)
    skip_scoring_inputs()
    todo = [r for r in records if r["solver"] in rows and (r["map"], r["solver"]) not in done]
    todo = todo[::-1] if args.reverse else todo
    print(f"{len(todo)} (map, row) to plan again ({len(done)} done)", file=sys.stderr)
    for k, rec in enumerate(todo):
        path = rec["skymap"]
        if args.maps_root is not None:
            path = str(args.maps_root) + path.removeprefix("/work/population_o4_real")
        captured.clear()
        t0 = time.perf_counter()
        row = per_map.bench_map(path, dataclasses.replace(settings, solvers=(rec["solver"],)), raise_errors=True)[0]
        plan = captured.get("plan")
        frozen = {c: rec["row"].get(c) for c in COMPARED}
        again = {c: row.get(c) for c in COMPARED}
        ok = plan is not None and all(same(frozen[c], again[c]) for c in COMPARED)
        out = dict(map=rec["map"], solver=rec["solver"], reproduced=ok, frozen=frozen, again=again,
                   status=row.get("status"), plan=plan.to_document() if plan is not None else None)
        with gzip.open(args.out, "at") as fh:
            fh.write(json.dumps(out) + "\n")
        print(f"{k + 1}/{len(todo)} {rec['solver']} {rec['map'][:20]} reproduced={ok} "
              f"{time.perf_counter() - t0:.1f}s", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
