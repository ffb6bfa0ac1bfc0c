"""Every real O4 neutron-star public sky map at hand, planned through the service path and scored independently.

For each map of ``MAPS`` (``shared/data/skymaps/public``; their provenance is
in ``shared/data/skymaps/SOURCES.md``) this runs ``mushrooms plan MAP``
(the command a person runs; horizon from the map's event time, the
configuration's default solver) and ``mushrooms plan MAP --solver greedy``
in a subprocess with this tree on ``PYTHONPATH``, reads each plan document
back, and scores it with the independent scoring
(:mod:`mushrooms.evaluation.independent_scoring`): the plan's queue set
executed by the executor (nominal, and ``--perturbations`` seeded draws of
the overheads and of the overheads with weather), ZTF's two-detection rule,
the Bulla (2019) kilonova grid drawn per source, SFD extinction, and the
campaigns' flat median depth (20.8; the perturbed columns too), with the
nominal record also scored under ztf_sim's formula and the planner's own
depth model.  The sources are drawn from each map's 3-D posterior
(a real event has no known truth), the same sources and perturbation seeds
for both rows of a map.

Usage::

    python benchmarks/science/real_o4_maps.py OUT_DIR [--perturbations 8] [--sources 2000] [--reuse-plans]

Writes ``OUT_DIR/real_o4_maps.csv`` (one row per map and solver),
``OUT_DIR/real_o4_maps.md`` (the table) and the plan documents under
``OUT_DIR/plans/``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PUBLIC = Path(os.environ.get("MUSHROOMS_PUBLIC_MAPS", "/work/shared/data/skymaps/public"))
#: The O4 maps with a neutron star (shared/data/skymaps/SOURCES.md), and what each is.
MAPS = {
    "S230518h": ("S230518h_Bilby.offline0.multiorder.fits", "NSBH, offline Bilby"),
    "S230529ay": ("S230529ay_Bilby.offline0.multiorder.fits", "GW230529, L1 only, offline Bilby"),
    "S230627c": ("S230627c_Bilby.multiorder.fits", "NSBH/BBH, Bilby"),
    "S230731an": ("S230731an_bayestar.multiorder.fits", "BAYESTAR"),
    "S231113bw": ("S231113bw_Bilby.multiorder.fits", "Bilby"),
    "G476954": ("G476954_bayestar.fits.gz", "very probably S240422ed's preliminary BAYESTAR map"),
}
SOLVERS = ("default", "greedy")
DEPTHS = ("campaign", "ztf_sim", "mushrooms")


def plan_map(path: Path, solver: str, out: Path, reuse: bool = False) -> tuple[dict, float]:
    """Run ``mushrooms plan`` on a map; its plan document and the wall time (s; NaN for a reused document)."""
    if reuse and out.exists():
        return json.loads(out.read_text()), float("nan")
    cmd = [sys.executable, "-m", "mushrooms.cli", "plan", str(path), "-o", str(out), "--brief"]
    if solver != "default":
        cmd += ["--solver", solver]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"mushrooms plan {path.name} ({solver}) exit {done.returncode}: {done.stderr[-500:]}")
    return json.loads(out.read_text()), wall


def score_map(name: str, args: argparse.Namespace, out_dir: Path) -> list[dict]:
    """Both rows of one map."""
    from astropy.time import Time

    from mushrooms.evaluation.independent_scoring import (independent_scores, posterior_sources, score_record,
                                                          scoring_seed)
    from mushrooms.evaluation.perturbed_execution import execute_perturbed, submitted_queues
    from mushrooms.scheduler_core.config import PlanningConfig
    from mushrooms.scheduler_core.plan.document import Plan
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    file, note = MAPS[name]
    path = PUBLIC / file
    nside = PlanningConfig().nside
    sm = read_skymap(path, nside=nside)
    fields = load_ztf_fields()
    footprints = field_footprints(fields, nside)
    sources = posterior_sources(sm, args.sources, seed=scoring_seed(sm.sha256))
    merger = Time(sm.event_time, scale="utc")
    rows = []
    for solver in SOLVERS:
        doc, wall = plan_map(path, solver, out_dir / "plans" / f"{name}-{solver}.json", args.reuse_plans)
        row = dict(event=name, map=file, note=note, solver=solver, area90_deg2=round(float(sm.credible_area(0.9)), 1),
                   distmean_mpc=round(float(sm.distmean), 1) if sm.distmean is not None else "",
                   plan_wall_s=round(wall, 1))
        if doc.get("type") == "not_observable":  # the service's answer: nothing to observe, nothing detected
            row.update(plan_solver="not_observable", n_exposures=0, coverage=0.0, coverage_as_executed=0.0,
                       answer="; ".join(doc.get("reasons", []))[:300])
            rows.append(row)
            print(json.dumps(row), flush=True)
            continue
        plan = Plan.from_document(doc)
        row.update(plan_solver=plan.metrics.solver, n_exposures=len(plan.observations),
                   coverage=round(float(plan.metrics.coverage), 4),
                   coverage_as_executed=_num(getattr(plan.metrics, "coverage_as_executed", None)))
        scores = independent_scores(plan, merger, sources, footprints, fields, DEPTHS[0], args.perturbations,
                                    seed=scoring_seed(sm.sha256, "perturbations"))
        row.update({k: round(v, 4) for k, v in scores.items()})
        record = execute_perturbed(plan, None, submitted_queues(plan)) if plan.observations else ()
        for depth in DEPTHS[1:]:
            s = score_record(record, merger, sources, footprints, fields, depth)
            row[f"efficiency_one_detection_{depth}"] = round(s["one_detection"], 4)
            row[f"efficiency_two_detections_{depth}"] = round(s["two_detections"], 4)
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def _num(x: object) -> object:
    return "" if x is None else round(float(x), 4)


def table(rows: list[dict], args: argparse.Namespace) -> str:
    """The Markdown table (efficiencies in per cent of the sources)."""
    head = ("| event | solver | 90 % area deg² | mean dist Mpc | exposures | coverage planned | executed | "
            "1 det. | **2 det.** | 2 det. overheads | 2 det. weather | 2 det. ztf_sim depth | 2 det. planner depth |")
    lines = [head, "|" + "---|" * 13]
    def pct(r: dict, k: str) -> str:
        return f"{100 * r[k]:.2f}" if r.get(k, "") != "" else ("0" if not r["n_exposures"] else "–")

    for r in rows:
        cells = [f"{r['event']}", f"{r['solver']} ({r['plan_solver']})", f"{r['area90_deg2']}", f"{r['distmean_mpc']}",
                 f"{r['n_exposures']}", f"{r['coverage']:.3f}", f"{r['coverage_as_executed']}",
                 pct(r, "efficiency_one_detection"), f"**{pct(r, 'efficiency_two_detections')}**",
                 pct(r, "efficiency_two_detections_overheads"), pct(r, "efficiency_two_detections_perturbed"),
                 pct(r, "efficiency_two_detections_ztf_sim"), pct(r, "efficiency_two_detections_mushrooms")]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + (f"\n\nEfficiencies in % of {args.sources} sources per map drawn from its 3-D "
                               f"posterior; depth: the campaigns' flat 20.8 unless named; {args.perturbations} "
                               "seeded perturbation draws of each kind.\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--perturbations", type=int, default=8)
    ap.add_argument("--sources", type=int, default=2000)
    ap.add_argument("--maps", default=",".join(MAPS))
    ap.add_argument("--reuse-plans", action="store_true", help="score the plan documents already in OUT/plans")
    args = ap.parse_args()
    (args.out / "plans").mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.maps.split(","):
        rows += score_map(name, args, args.out)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(args.out / "real_o4_maps.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    (args.out / "real_o4_maps.md").write_text(table(rows, args))
    print(table(rows, args))


if __name__ == "__main__":
    main()
