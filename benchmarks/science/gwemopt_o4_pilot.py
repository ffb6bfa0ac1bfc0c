#!/usr/bin/env python3
"""Pilot of the release's rows (issue 55) on a few shared simulated maps, in the population's CSV layout.

Per map (``bench_map``, one map at a time, resumable): the six rows
``service``, ``service-grg``, ``greedy``, ``gwemopt-o4``, ``gwemopt-skyportal``
and ``gwemopt-repaired`` under the worktree's ``config.toml`` (``--config``),
gwemopt's raw schedules cached under ``benchmarks/results/science/gwemopt-cache``
(the existing cache; the legacy ``gwemopt`` schedules of the maps there are
reused by ``gwemopt-repaired``).  Each row becomes a population row
(:func:`~mushrooms.evaluation.study.population_rows.population_row`: event
``<set>-<id>``, class and injected distance from the maps' ``truth_all.csv``),
written to ``OUT/results.csv`` after every map; ``OUT/tables.md`` is rebuilt
from that CSV alone (``benchmarks/science/release_tables.py``).

    MUSHROOMS_GWEMOPT_PYTHON=/work/gwemopt-venv/bin/python nice -n 19 \\
        .venv/bin/python benchmarks/science/gwemopt_o4_pilot.py [--maps bns_o3/1.fits ...] [--out DIR]

The study settings are the study's (:func:`~mushrooms.evaluation.study.run.study_bench_settings`: the fixed source
model, one solver thread).  The service rows plan under ``[scheduler]`` as the config says (``deterministic``
included once the work budget exists); the wall-clock budget otherwise, so they depend on the machine's load.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

from astropy.utils import iers

from mushrooms.evaluation.bench.per_map import bench_map
from mushrooms.evaluation.bench.settings import BenchSettings
from mushrooms.evaluation.study.population_rows import population_row, read_population_csv, write_population_csv
from mushrooms.evaluation.study.release_tables import RELEASE_ROWS, release_tables
from mushrooms.evaluation.study.run import study_bench_settings
from mushrooms.tool.config import load_config

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SIMULATED = Path("/work/shared/data/skymaps/simulated")
#: Default pilot: four BNS and two NSBH maps of the shared O3-like sets.
DEFAULT_MAPS = ("bns_o3/0.fits", "bns_o3/1.fits", "bns_o3/2.fits", "bns_o3/3.fits",
                "nsbh_o3/allsky_0to399/3.fits", "nsbh_o3/allsky_0to399/4.fits")


def truth(simulated: Path) -> dict[str, dict[str, str]]:
    """``truth_all.csv`` by map path (relative to ``simulated``)."""
    with open(simulated / "truth_all.csv", newline="") as fh:
        return {r["skymap"]: r for r in csv.DictReader(fh)}


def event_of(rel: str, facts: dict[str, str]) -> dict[str, object]:
    """The population's event record of one shared map: its name, class and injected distance."""
    cls = "BNS" if facts["set"].startswith("bns") else "NSBH"
    return dict(event=f"{facts['set']}-{facts['coinc_event_id']}", event_class=cls,
                distance_mpc=float(facts["distance_mpc"]))


def settings_for(config_path: Path, cache: Path, injections: int) -> BenchSettings:
    """The study's bench settings for the release's rows, gwemopt cached under ``cache``."""
    import dataclasses

    config = load_config(config_path)
    bench = dataclasses.replace(config.bench, gwemopt_cache_dir=str(cache))
    return study_bench_settings(BenchSettings(config=config.scheduler, bench=bench, solvers=RELEASE_ROWS,
                                              n_injections=injections,
                                              supersede_min_gain=float(config.daemon.supersede_min_gain)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=list(DEFAULT_MAPS), help="paths under --simulated")
    ap.add_argument("--simulated", type=Path, default=SIMULATED)
    ap.add_argument("--config", type=Path, default=ROOT / "config.toml")
    ap.add_argument("--cache", type=Path, default=ROOT / "benchmarks/results/science/gwemopt-cache")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/science/gwemopt_o4/pilot")
    ap.add_argument("--injections", type=int, default=10_000)
    args = ap.parse_args()
    iers.conf.auto_download = False
    settings = settings_for(args.config, args.cache, args.injections)
    facts = truth(args.simulated)
    csv_path = args.out / "results.csv"
    rows = read_population_csv(csv_path) if csv_path.exists() else []
    for rel in args.maps:
        event = event_of(rel, facts[rel])
        have = {r["solver"] for r in rows if r["event"] == event["event"]}
        if set(RELEASE_ROWS) <= have:
            print(f"{rel}: done before", flush=True)
            continue
        t0 = time.perf_counter()
        bench_rows = bench_map(args.simulated / rel, settings)
        rows = [r for r in rows if r["event"] != event["event"]] + [population_row(r, event) for r in bench_rows]
        write_population_csv(rows, csv_path)
        print(f"{rel}: {time.perf_counter() - t0:.0f} s; " + ", ".join(
            f"{r['solver']} {r['status']} {r['runtime_s']}" for r in bench_rows), flush=True)
    (args.out / "tables.md").write_text(release_tables(read_population_csv(csv_path)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
