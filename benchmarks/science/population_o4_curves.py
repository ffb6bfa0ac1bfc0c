#!/usr/bin/env python3
"""The executed curves of the release's plans made again: coverage after each done exposure, for the matched-time table.

Reads the plans of ``population_o4_replan.py`` (JSON lines, gzipped: ``map``, ``solver``, ``reproduced``,
``frozen``, ``plan``), executes each plan's queue set on time with this checkout's executor
(:func:`mushrooms.evaluation.matched_time.plan_curve`: the executor and pair rule of the ``coverage_executed``
column) on its sky map, and writes ``study/executed_curves.jsonl.gz`` (``event``, ``solver``, ``map``,
``reproduced``, ``curve``: the time-ordered prefix, ``subset``: the covered fields best first), the file the
release tables read.  A plan counts as reproduced only when the
replan matched the frozen record and the curve ends on the record's executed coverage and open-shutter
seconds (this executor is the frozen one's).  Events are named as in ``results.csv`` from the committed chunks.

    .venv/bin/python benchmarks/science/population_o4_curves.py PLANS.jsonl.gz [...] \\
        [--release benchmarks/results/science/population_o4] [--maps-root /work/population_o4_real] [--resume]
"""

from __future__ import annotations

import argparse
import gzip
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _entries(paths: list[Path]) -> list[dict]:
    out: dict[tuple[str, str], dict] = {}
    for p in paths:
        with gzip.open(p, "rt") as fh:
            for line in fh:
                try:
                    e = json.loads(line)
                except json.JSONDecodeError:  # a line cut by a stopped replan
                    continue
                out[(e["map"], e["solver"])] = e
    return list(out.values())


def _listed(curve) -> list | None:
    return None if curve is None else [[round(float(a), 1), round(float(b), 6)] for a, b in curve]


def _ends_on_record(curve, frozen: dict) -> bool:
    """The curve's last point is the frozen row's executed open-shutter seconds and coverage."""
    try:
        return (abs(float(curve[-1, 0]) - float(frozen["open_shutter_executed_s"])) <= 0.05
                and abs(float(curve[-1, 1]) - float(frozen["coverage_as_executed"])) <= 1e-6)
    except (TypeError, ValueError, KeyError):
        return False


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plans", type=Path, nargs="+")
    ap.add_argument("--release", type=Path, default=HERE.parent / "results" / "science" / "population_o4")
    ap.add_argument("--maps-root", type=Path, default=Path("/work/population_o4_real"),
                    help="where the maps the records name are (read only)")
    ap.add_argument("--resume", action="store_true", help="keep the curves the output already has")
    args = ap.parse_args()
    from mushrooms.evaluation.matched_time import plan_curve
    from mushrooms.evaluation.study.matched_tables import MATCHED_ROWS, write_curves
    from mushrooms.evaluation.study.population_rows import population_events
    from mushrooms.scheduler_core.plan.document import Plan
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.sky.skymap import read_skymap
    from mushrooms.tool.config import load_config

    config = load_config(args.release / "study" / "config.toml").scheduler
    events = population_events(sorted((args.release / "population" / "chunks").glob("events-*.xml.gz")),
                               prefix="o4real")
    footprints = field_footprints(load_ztf_fields(), config.nside)
    target = args.release / "study" / "executed_curves.jsonl.gz"
    kept = {}
    if args.resume and target.exists():  # the curves already made from the same plans are not made again
        with gzip.open(target, "rt") as fh:
            kept = {(d["map"], d["solver"]): d for d in map(json.loads, fh)
                    if "subset" in d and d["solver"] in MATCHED_ROWS}
    entries = sorted((e for e in _entries(args.plans) if e["solver"] in MATCHED_ROWS), key=lambda e: e["map"])
    out, maps = [kept[k] for k in kept if k not in {(e["map"], e["solver"]) for e in entries}], {}
    for e in entries:
        if (e["map"], e["solver"]) in kept:
            out.append(kept[(e["map"], e["solver"])])
            continue
        sha, cid, options = e["map"].split(":", 2)
        event = events.get((sha, int(cid)))
        if event is None:
            print(f"{e['map']}: not an event of the committed chunks, skipped", file=sys.stderr)
            continue
        if e["map"] not in maps:
            path = args.maps_root / "cache" / "maps" / f"{sha}-{options}" / f"{cid}.fits"
            maps = {e["map"]: read_skymap(str(path), nside=config.nside)}
        curve = best = None
        ok = bool(e.get("reproduced")) and e.get("plan") is not None
        if e.get("plan") is not None:
            curve, best = plan_curve(Plan.from_document(e["plan"]), footprints, maps[e["map"]].prob)
            ok = ok and _ends_on_record(curve, e["frozen"]) and abs(
                float(best[-1, 1]) - float(e["frozen"]["coverage_as_executed"])) <= 1e-6
        out.append(dict(event=event["event"], solver=e["solver"], map=e["map"], reproduced=ok,
                        curve=_listed(curve), subset=_listed(best)))
        print(f"{event['event']} {e['solver']} reproduced={ok} n={0 if curve is None else len(curve) - 1}",
              file=sys.stderr)
    out.sort(key=lambda d: (d["event"], d["solver"]))
    write_curves(out, target)
    print(f"{len(out)} curves, {sum(d['reproduced'] for d in out)} reproduced -> {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
