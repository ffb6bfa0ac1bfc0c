#!/usr/bin/env python3
"""The deciding row of issue 55's matched-time question: the service planned under gwemopt-o4's telescope time.

For each event of the committed snapshot (``study/results.jsonl.gz``), the service (and, with ``--rows``,
service-grg) is planned by the CURRENT code (the tree on ``PYTHONPATH``, not the frozen af0ff7d) along the study's
own path (:func:`bench_map`, the study's ``config.toml``, deterministic work budget) with
``[scheduler] max_open_shutter_s`` = gwemopt-o4's open-shutter seconds on that event (``--budget executed``, the
default: what its queue set executed in the study's executor; ``planned``: the seconds its plan asked for).
The plan is scored by the part of the bench's scorer the matched-time tables use (the light scorer of
``population_o4_replan.py``: the executed queue set's coverage and open-shutter seconds, the pair-rule planned
coverage, the exposure count); the detection columns are not computed.  An event where gwemopt-o4 has no open
shutter gets no plan (a budget of 0 s covers nothing): the row is written with zeros and ``planned: false``.

Output: one JSON line per (event, row), appended (a re-run goes on where it stopped), gzipped.

    PYTHONPATH=$PWD nice -n 10 /work/main/.venv/bin/python benchmarks/science/population_o4_matched_budget.py \\
        --records benchmarks/results/science/population_o4/study/results.jsonl.gz \\
        --config benchmarks/results/science/population_o4/study/config.toml --out OUT.jsonl.gz [--until HH:MM]
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import gzip
import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from population_o4_replan import light_scorer, settings_of, skip_scoring_inputs  # noqa: E402

#: The cells kept for each row (the light scorer's).
KEPT = ("coverage_reported", "coverage_as_executed", "open_shutter_executed_s", "coverage_pairs", "open_shutter_s",
        "n_exposures")


def budgets(records: list[dict], which: str) -> dict[str, float]:
    """gwemopt-o4's open-shutter seconds on each event (``executed`` or ``planned``)."""
    column = "open_shutter_executed_s" if which == "executed" else "open_shutter_s"
    return {r["map"]: float(r["row"].get(column) or 0.0) for r in records if r["solver"] == "gwemopt-o4"}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=Path, required=True)
    ap.add_argument("--config", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--rows", default="service", help="service and/or service-grg, comma-separated")
    ap.add_argument("--budget", choices=("executed", "planned"), default="executed")
    ap.add_argument("--until", help="UTC HH:MM: start no plan after this time")
    args = ap.parse_args()
    from mushrooms.evaluation.bench import per_map
    from mushrooms.evaluation.bench.run import worker_init

    worker_init()
    records = [json.loads(line) for line in gzip.open(args.records, "rt")]
    cap_of = budgets(records, args.budget)
    skymap_of = {r["map"]: r["skymap"] for r in records}
    settings = settings_of(args.config, Path(tempfile.mkdtemp(prefix="no-gwemopt-")))
    done = set()
    if args.out.exists():
        done = {(d["map"], d["row"]) for d in map(json.loads, gzip.open(args.out, "rt"))}
    captured: dict = {}
    per_map.score_plan = light_scorer(captured)
    skip_scoring_inputs()
    rows = [r for r in args.rows.split(",") if r]
    todo = [(m, row) for m in cap_of for row in rows if (m, f"{row}-capped") not in done]
    print(f"{len(todo)} (event, row) to plan ({len(done)} done); budget = gwemopt-o4's {args.budget} open shutter",
          file=sys.stderr)
    for k, (name, row) in enumerate(todo):
        if args.until and dt.datetime.now(dt.timezone.utc).strftime("%H:%M") >= args.until:
            print(f"stopped at --until {args.until}", file=sys.stderr)
            break
        cap = cap_of[name]
        out = dict(map=name, row=f"{row}-capped", budget=args.budget, cap_s=cap)
        t0 = time.perf_counter()
        if cap < 1.0:  # gwemopt-o4 executed nothing: no telescope time to plan
            out.update(planned=False, cells={c: 0.0 for c in KEPT}, status="no_budget", plan=None)
        else:
            config = dataclasses.replace(settings.config, max_open_shutter_s=cap)  # a keyed row adds its keys
            run = dataclasses.replace(settings, config=config, solvers=(row,))
            captured.clear()
            result = per_map.bench_map(skymap_of[name], run, raise_errors=True)[0]
            plan = captured.get("plan")
            out.update(planned=True, cells={c: result.get(c) for c in KEPT}, status=result.get("status"),
                       solver_detail=result.get("solver_detail"), commit=result.get("commit"),
                       plan=plan.to_document() if plan is not None else None)
        out["row"] = f"{row}-capped"
        out["wall_s"] = round(time.perf_counter() - t0, 1)
        with gzip.open(args.out, "at") as fh:
            fh.write(json.dumps(out) + "\n")
        c = out["cells"]
        print(f"{k + 1}/{len(todo)} {row} {name[:24]} cap={cap:.0f}s open={c['open_shutter_s']} "
              f"executed={c['coverage_as_executed']} {out['wall_s']}s", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
