"""Fixed 300 s against the exposure menu , on the shared maps with distance layers.

For each map: one coverage plan (the configured scheduler with
``time_limit_s - detection_time_limit_s``, as ``planner.optimise`` gives it),
then the detection stage twice from that same plan, within the same
``detection_time_limit_s``: without a menu (every visit ``exposure_s``) and
with ``--menu``.  The pair shares the map, the start and the coverage plan,
so the difference is the menu's.  Each published plan goes through the
checker and is scored exactly (X1) under the three paper curves; (X1) is the
exact expectation of the bench's injection efficiency, so it carries no
Monte Carlo error: the errors quoted are the paired standard errors of the
mean difference over maps.  A map counts as better / worse when the
difference exceeds ``min_gain`` (0.001).

    python benchmarks/quality/exposure_menu.py [--maps bns_o3,nsbh_o3] [--limit N] [--nside 128] \
        [--menu 30,60,120,300,600] -o benchmarks/results/quality/exposure_menu/exposure_menu.csv \
        --plot benchmarks/results/quality/exposure_menu/exposure_vs_distance.png
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))  # benchmarks/common: the shared helpers
from csv_rows import write_rows  # noqa: E402

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from mushrooms.scheduler_core.config import PlanningConfig  # noqa: E402
from mushrooms.scheduler_core.plan.checker import check_plan  # noqa: E402
from mushrooms.scheduler_core.planner import build_plan, run_scheduler  # noqa: E402
from mushrooms.scheduler_core.prepare import prepare_problem  # noqa: E402
from mushrooms.scheduler_core.schedulers.detection.stage import detection_stage, plan_expected_detections  # noqa: E402
from mushrooms.scheduler_core.schedulers.gain import drop_low_gain, published_coverage  # noqa: E402
from mushrooms.scheduler_core.sky.skymap import read_skymap  # noqa: E402
from mushrooms.scheduler_core.source.kilonova import load_kilonova  # noqa: E402

MAPS = Path("/work/shared/data/skymaps/simulated")
CURVES = ("optimistic", "conservative", "nsbh")


def scaled(sm, k: float):
    """The map with every distance times k (DISTNORM / k²: each pixel's posterior scaled)."""
    return dataclasses.replace(sm, distmu=sm.distmu * k, distsigma=sm.distsigma * k, distnorm=sm.distnorm / k ** 2,
                               distmean=sm.distmean * k, sha256=f"{sm.sha256}-x{k:g}")


def run_map(path: Path, cfg: PlanningConfig, menu: tuple[float, ...], solver: str, scale: float | None = None
            ) -> dict:
    """One map: the coverage plan, then the detection stage without and with the menu."""
    sm = read_skymap(path, nside=cfg.nside)
    if scale is not None:  # a sweep: the map with its distances scaled (its rows named sweep/<map> x<k>)
        sm = scaled(sm, scale)
    problem = prepare_problem(sm, cfg, sm.event_time)
    covering = dataclasses.replace(problem, config=dataclasses.replace(
        cfg, objective="coverage", time_limit_s=cfg.time_limit_s - cfg.detection_time_limit_s))
    t0 = time.perf_counter()
    cov = run_scheduler(covering, solver)
    name = str(path.relative_to(MAPS)) if path.is_relative_to(MAPS) else path.name
    row = {"skymap": name if scale is None else f"sweep/{name} x{scale:g}", "distmean_mpc": round(float(sm.distmean), 1),
           "coverage_s": round(time.perf_counter() - t0, 2)}
    kilonovae = {c: load_kilonova(c) for c in CURVES}
    for tag, m in (("fixed", ()), ("menu", menu)):
        p = dataclasses.replace(problem, config=dataclasses.replace(cfg, exposure_menu_s=m))
        t = time.perf_counter()
        det = detection_stage(p, sm, cov)
        row[f"{tag}_stage_s"] = round(time.perf_counter() - t, 2)
        kept = drop_low_gain(det, p.footprints, p.prob, cfg.min_gain).observations
        row[f"{tag}_choice"] = det.detection.choice
        row[f"{tag}_coverage"] = round(published_coverage(p, det), 5)
        for c, kn in kilonovae.items():
            row[f"{tag}_E_{c}"] = round(plan_expected_detections(p, sm, kept, kn), 6)
        plan = build_plan(p, det, sm, solver)
        report = check_plan(plan, sm, p.config)
        row[f"{tag}_valid"] = bool(report.ok)
        per = {o.field_id: o.exposure_s for o in plan.observations}
        w = {f: p.footprints.coverage({f}, p.prob) for f in per}
        row[f"{tag}_exposure_pw_s"] = round(sum(w[f] * e for f, e in per.items()) / max(sum(w.values()), 1e-12), 1)
        row[f"{tag}_exposures"] = " ".join(f"{e:g}:{n}" for e, n in zip(*np.unique(list(per.values()),
                                                                                  return_counts=True)))
        row[f"{tag}_n_fields"] = len(per)
    return row


def summary(rows: list[dict], min_gain: float) -> list[str]:
    out = []
    for pop in sorted({r["skymap"].split("/")[0] for r in rows}) + ["all"]:
        sel = [r for r in rows if pop == "all" or r["skymap"].startswith(pop + "/")]
        mixed = sum(any(not e.startswith("300:") for e in str(r["menu_exposures"]).split()) for r in sel)
        out.append(f"{pop}: {len(sel)} maps; plans valid under the checker: menu {sum(r['menu_valid'] for r in sel)}"
                   f"/{len(sel)}, fixed {sum(r['fixed_valid'] for r in sel)}/{len(sel)}; the menu run published "
                   f"exposures other than 300 s on {mixed} maps (a detection-stage plan on "
                   f"{sum(r['menu_choice'] == 'detection' for r in sel)}, fixed run on "
                   f"{sum(r['fixed_choice'] == 'detection' for r in sel)})")
        for c in CURVES:
            a = np.array([r[f"fixed_E_{c}"] for r in sel], float)
            b = np.array([r[f"menu_E_{c}"] for r in sel], float)
            d = b - a
            se = d.std(ddof=1) / np.sqrt(d.size) if d.size > 1 else float("nan")
            ratio = b.sum() / a.sum() if a.sum() > 0 else float("nan")
            out.append(f"  {c:12s} E fixed {a.mean():.4f}  menu {b.mean():.4f}  diff {d.mean():+.4f} ± {se:.4f} "
                       f"(paired s.e.)  total x{ratio:.3f}  better {int((d > min_gain).sum())} worse "
                       f"{int((d < -min_gain).sum())}")
        ca = np.array([r["fixed_coverage"] for r in sel])
        cb = np.array([r["menu_coverage"] for r in sel])
        dc = cb - ca
        out.append(f"  coverage     fixed {ca.mean():.4f}  menu {cb.mean():.4f}  diff {dc.mean():+.4f} ± "
                   f"{dc.std(ddof=1) / np.sqrt(dc.size) if dc.size > 1 else float('nan'):.4f}")
        st = np.array([r["menu_stage_s"] for r in sel])
        out.append(f"  detection stage wall time (s): fixed median {np.median([r['fixed_stage_s'] for r in sel]):.2f}, "
                   f"menu median {np.median(st):.2f}, max {st.max():.2f}; coverage stage median "
                   f"{np.median([r['coverage_s'] for r in sel]):.2f}")
    return out


def plot(rows: list[dict], path: Path) -> None:
    """Chosen exposure (probability-weighted over a plan's fields) against the map's mean distance."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for pop, colour in (("bns_o3", "tab:blue"), ("nsbh_o3", "tab:orange"), ("bns_o3_pipeline", "tab:green")):
        sel = [r for r in rows if r["skymap"].startswith(pop + "/") and int(r["menu_n_fields"]) > 0]
        if not sel:
            continue
        mixed = [r for r in sel if str(r["menu_exposures"]).count(":") > 1 or "300:" not in str(r["menu_exposures"])]
        fixed = [r for r in sel if r not in mixed]
        ax.scatter([float(r["distmean_mpc"]) for r in mixed], [float(r["menu_exposure_pw_s"]) for r in mixed],
                   color=colour, label=f"{pop}: menu plan published")
        ax.scatter([float(r["distmean_mpc"]) for r in fixed], [float(r["menu_exposure_pw_s"]) for r in fixed],
                   facecolors="none", edgecolors=colour, label=f"{pop}: a 300 s plan kept")
    ax.axhline(300.0, color="grey", ls="--", lw=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(25, 700)
    ax.set_yticks([30, 60, 120, 300, 600])
    ax.set_yticklabels(["30", "60", "120", "300", "600"])
    ax.minorticks_off()
    ax.set_xlim(25, 800)
    ax.set_xticks([30, 50, 100, 200, 300, 500, 800])
    ax.set_xticklabels(["30", "50", "100", "200", "300", "500", "800"])
    ax.set_xlabel("map's posterior mean distance (Mpc)")
    ax.set_ylabel("exposure (s), probability-weighted\nmean over the plan's fields")
    ax.set_title("Menu [30, 60, 120, 300, 600] s: exposure chosen vs distance (shared O3 maps)")
    sweep = sorted((r for r in rows if r["skymap"].startswith("sweep/") and int(r["menu_n_fields"]) > 0),
                   key=lambda r: float(r["distmean_mpc"]))
    if sweep:
        ax.plot([float(r["distmean_mpc"]) for r in sweep], [float(r["menu_exposure_pw_s"]) for r in sweep], "k-^",
                label=f"{sweep[0]['skymap'].split(' ')[0][6:]} with distances scaled")
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _typed(v: str):
    """A CSV cell back as bool, number or text."""
    if v in ("True", "False"):
        return v == "True"
    try:
        return float(v)
    except ValueError:
        return v


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", default="bns_o3,nsbh_o3")
    ap.add_argument("--limit", type=int, default=0, help="first N maps of each set (0: all)")
    ap.add_argument("--nside", type=int, default=128)
    ap.add_argument("--solver", default="hybrid")
    ap.add_argument("--menu", default="30,60,120,300,600")
    ap.add_argument("--sweep", help="one map (path) planned with its distances scaled by --factors")
    ap.add_argument("--factors", default="0.25,0.5,1,1.5,2,3")
    ap.add_argument("-o", "--output", type=Path, required=True, help="CSV of the rows (--replot: CSVs, comma-separated)")
    ap.add_argument("--replot", action="store_true", help="only redraw --plot from the rows in --output")
    ap.add_argument("--plot", type=Path)
    args = ap.parse_args()
    if args.replot:  # the rows of one or more CSVs (comma-separated --output), typed again
        rows = []
        for name in str(args.output).split(","):
            with open(name) as fh:
                rows += [{k: _typed(v) for k, v in r.items()} for r in csv.DictReader(fh)]
        if args.plot:
            plot(rows, args.plot)
        lines = summary([r for r in rows if not r["skymap"].startswith("sweep/")], PlanningConfig().min_gain)
        print("\n".join(lines))
        return
    cfg = PlanningConfig(nside=args.nside)
    menu = tuple(float(x) for x in args.menu.split(","))
    paths = []
    for name in args.maps.split(","):
        found = sorted((MAPS / name).rglob("*.fits"),
                       key=lambda p: (str(p.parent), int(p.stem) if p.stem.isdigit() else 0))
        paths += found[:args.limit] if args.limit else found
    jobs = [(p, None) for p in paths]
    if args.sweep:
        jobs = [(Path(args.sweep), float(k)) for k in args.factors.split(",")]
    rows = []
    for path, k in jobs:
        rows.append(run_map(path, cfg, menu, args.solver, k))
        r = rows[-1]
        print(f"{r['skymap']:18s} {r['distmean_mpc']:6.0f} Mpc  E_cons fixed {r['fixed_E_conservative']:.4f} menu "
              f"{r['menu_E_conservative']:.4f}  cov {r['fixed_coverage']:.3f}/{r['menu_coverage']:.3f}  "
              f"exp {r['menu_exposure_pw_s']:.0f} s  [{r['menu_exposures']}]  valid {r['fixed_valid']}/{r['menu_valid']}",
              flush=True)
        write_rows(args.output, rows)
    lines = summary(rows, cfg.min_gain)
    print("\n".join(lines))
    args.output.with_suffix(".txt").write_text("\n".join(lines) + "\n")
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()
