"""Issue 52, findings 12-13: what ZTF executes of a plan's queue set under first-wins and last-wins, before/after.

ztf_sim's main loop takes the *last* valid queue in submission order (``check_for_timed_queue_and_switch``);
the executor before issue 52 modelled the *first*.  Per map and solver this runs:

* **before**: the plan and the queue set of a checkout of main (``--before``, e.g. ``git archive main``),
  planned and exported in a subprocess with that tree first on ``PYTHONPATH``; its own
  ``coverage_as_executed`` (main's model);
* **after**: the same plan exported by this tree (the export's effect alone), and this tree's own plan
  and queue set (the planner's choice may change with the model: Q15);

and executes every queue set with this tree's executor (ztf_sim's rules: refused slews retried, an emptied
queue costs a survey exposure) under ``switch = first`` and ``switch = last``, on time and 15/30/60 min late,
scoring cadence-valid coverage (Q14) and, for a sequence of three filters, the coverage of the fields whose
whole sequence is executed (Q21) with the third visits lost or too soon.

    python benchmarks/execution/switch_rules.py --before /tmp/mainsnap [--solvers greedy hybrid]
        [--grg] [--out FILE] MAP ...

One JSON line per map and solver in FILE (resumable); FILE.summary.txt the table.  Not a test.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LATES_S = (0.0, 900.0, 1800.0, 3600.0)


def export_main(argv: list[str]) -> int:
    """``--export MAP SOLVER GRG OUT``: plan and export with whatever ``mushrooms`` is first on the path."""
    path, solver, grg, out = Path(argv[0]), argv[1], argv[2] == "1", Path(argv[3])
    import dataclasses

    from mushrooms.offline import configure_astropy_offline

    configure_astropy_offline()
    from mushrooms.scheduler_core.plan.exports import to_trigger_queues
    from mushrooms.scheduler_core.planner import make_plan
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.tool.config import load_config

    cfg = load_config(ROOT / "config.toml").scheduler
    if grg:
        cfg = dataclasses.replace(cfg, filters=("g", "r", "g"), exposure_s=180.0)
    sm = read_skymap(path, nside=cfg.nside)
    t0 = time.perf_counter()
    plan = make_plan(sm, cfg, start=sm.event_time, solver=solver)
    t1 = time.perf_counter()
    queues = to_trigger_queues(plan) if plan.observations else []
    out.write_text(json.dumps({"plan": plan.to_document(), "queues": queues, "plan_s": round(t1 - t0, 2),
                               "export_s": round(time.perf_counter() - t1, 2), "tree": str(Path(
                                   sys.modules["mushrooms"].__file__).parents[1])}))
    return 0


def _subprocess_export(tree: Path, path: Path, solver: str, grg: bool, tmp: Path) -> dict:
    out = tmp / f"{tree.name}_{solver}.json"
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run([sys.executable, __file__, "--export", str(path), solver, "1" if grg else "0", str(out)],
                   env=env, check=True, cwd=str(tmp))
    return json.loads(out.read_text())


def _scores(plan, queues, footprints, prob) -> dict:
    """Executed coverage (and the whole sequence's) per switch rule and late start."""
    from mushrooms.scheduler_core.config import ONE_NIGHT_PAIR_S
    from mushrooms.scheduler_core.schedulers.as_executed import cadence_coverage, execute_plan_queues, sequence_coverage
    from mushrooms.scheduler_core.telescope.rules import QueueRules
    from mushrooms.scheduler_core.telescope.timing import TelescopeTiming

    cfg = plan.config or {}
    filters, cadence = tuple(cfg.get("filters", ("g", "r"))), float(cfg.get("cadence_s", 1800.0))
    out: dict = {}
    for rule in ("first", "last"):
        timing = TelescopeTiming(rules=QueueRules(switch=rule))
        for late in LATES_S:
            done = execute_plan_queues(plan, queues, late, timing)
            key = f"{rule}_{int(late // 60)}"
            out[key] = round(cadence_coverage(done, footprints, prob, filters, cadence), 6)
            if len(filters) > 2:
                separation = float(cfg.get("pair_max_s") or 0.0) or ONE_NIGHT_PAIR_S
                out[f"{key}_whole"] = round(sequence_coverage(done, footprints, prob, filters, cadence, separation), 6)
                if late == 0.0:
                    out[f"{key}_thirds"] = _third_visits(done, filters, cadence, plan)
    return out


def _third_visits(done, filters, cadence, plan) -> dict:
    """Of the covered fields: how many have their last visit executed on time, too soon, or not at all."""
    from mushrooms.scheduler_core.sequences import sequence_progress

    progress = sequence_progress(done, filters, cadence_s=cadence)
    count: dict[int, int] = {}
    for e in done:
        if e.status == "processed":
            count[e.field_id] = count.get(e.field_id, 0) + 1
    short = [f for f, p in progress.items() if p.done < len(filters)]
    return {"fields": len({o.field_id for o in plan.observations}), "covered": len(progress),
            "whole": len(progress) - len(short), "lost": sum(count[f] < len(filters) for f in short),
            "too_soon": sum(count[f] >= len(filters) for f in short)}


def run_map(path: Path, solver: str, before: Path, grg: bool) -> dict:
    from mushrooms.scheduler_core.plan.document import Plan
    from mushrooms.scheduler_core.plan.exports import to_trigger_queues
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    with tempfile.TemporaryDirectory() as tmp:
        old = _subprocess_export(before, path, solver, grg, Path(tmp))
        new = _subprocess_export(ROOT, path, solver, grg, Path(tmp))
    p0, p1 = Plan.from_document(old["plan"]), Plan.from_document(new["plan"])
    row = {"map": f"{path.parent.name}/{path.name}", "solver": solver, "grg": grg,
           "before_metric": p0.metrics.coverage_as_executed, "after_metric": p1.metrics.coverage_as_executed,
           "after_metric_whole": p1.metrics.sequence_coverage_as_executed,
           "planned_before": p0.metrics.coverage, "planned_after": p1.metrics.coverage,
           "same_plan": [o.__dict__ for o in p0.observations] == [o.__dict__ for o in p1.observations],
           "export_s_before": old["export_s"], "export_s_after": new["export_s"],
           "plan_s_before": old["plan_s"], "plan_s_after": new["plan_s"]}
    if not p0.observations:
        return dict(row, empty=True, load=os.getloadavg()[0])
    cfg = p0.config or {}
    sm = read_skymap(path, nside=int(cfg.get("nside", 256)))
    footprints = field_footprints(load_ztf_fields(), sm.nside)
    t0 = time.perf_counter()
    reexported = to_trigger_queues(p0)
    row["export_s_reexport"] = round(time.perf_counter() - t0, 2)
    row["before"] = _scores(p0, old["queues"], footprints, sm.prob)
    row["before_reexported"] = _scores(p0, reexported, footprints, sm.prob)
    row["after"] = _scores(p1, new["queues"], footprints, sm.prob) if p1.observations else {}
    row["load"] = os.getloadavg()[0]
    return row


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--export"]:
        return export_main(argv[1:])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+", type=Path)
    ap.add_argument("--before", type=Path, required=True, help="a checkout of main (its package root)")
    ap.add_argument("--solvers", nargs="+", default=["greedy", "hybrid"])
    ap.add_argument("--grg", action="store_true", help="g-r-g at 180 s instead of the configured pair")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from mushrooms.offline import configure_astropy_offline

    configure_astropy_offline()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if args.out.exists():
        done = {(r["map"], r["solver"]) for r in map(json.loads, args.out.read_text().splitlines())}
    with open(args.out, "a") as fh:
        for path in args.maps:
            for solver in args.solvers:
                if (f"{path.parent.name}/{path.name}", solver) in done:
                    continue
                row = run_map(path, solver, args.before, args.grg)
                fh.write(json.dumps(row) + "\n")
                fh.flush()
                print(f"{row['map']} {solver}: before {row.get('before', {}).get('first_0')} / "
                      f"{row.get('before', {}).get('last_0')}, after {row.get('after', {}).get('first_0')} / "
                      f"{row.get('after', {}).get('last_0')} (load {row['load']:.1f})", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
