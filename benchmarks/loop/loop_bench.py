#!/usr/bin/env python
"""Loop benchmark: list queue alone vs the daemon's re-plan after a weather closure.

For each shared sky map (the bench's list: every ``*.fits``/``*.fits.gz``
under ``/work/shared/data/skymaps``, sorted; ``--maps N`` takes N of them
spread evenly over that list), night 1 from the map's event time is planned
once and a seeded closure of 1-3 h falls at a random time of that night
(seed from the map's name and ``--seed``, so a subset keeps its closures).
Then :func:`mushrooms.evaluation.loop.loop_map`:

(a) the original plan executed as ZTF's list queue would under the closure;
(b) the same until the closure, the daemon's re-plan from the reopening
    (``plan_remaining`` on what (a) executed before the closure), executed
    from the reopening by the same executor;

and night 2 planned on each arm's record (what it adds).  Greedy plans both
the original and every re-plan by default (speed); ``--solver hybrid`` for
the daemon's solver.

Writes ``loop_bench.csv``, ``loop_bench.txt`` (the table and the summary)
and ``loop_gain.png`` (per-map coverage gain (b)-(a), sorted) into
``--out`` (default ``benchmarks/results/loop/loop_bench``) and prints the summary.

    PYTHONPATH=. python benchmarks/loop/loop_bench.py [--maps N] [--nside 128] [--solver greedy] [--seed 28]
"""

from __future__ import annotations

import argparse
import hashlib
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "common"))  # benchmarks/common: the shared helpers
from csv_rows import write_rows  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
MAPS = Path("/work/shared/data/skymaps")
OUT = ROOT / "benchmarks" / "results" / "loop" / "loop_bench"
#: A paired difference counts as better or worse beyond these (coverage, expected detections).
COV_TOL, DET_TOL = 1e-4, 1e-6

COLUMNS = ["map", "status", "night_start", "night_end", "closure_start", "closure_end", "closure_h",
           "plan_exposures", "plan_coverage", "coverage_clear", "coverage_cadence_clear", "replan_exposures", "replan_repeats",
           "done_a", "done_b", "coverage_a", "coverage_b", "coverage_gain", "coverage_cadence_a",
           "coverage_cadence_b", "detections_a", "detections_b", "detections_gain",
           "night2_added_a", "night2_added_b", "two_nights_a", "two_nights_b", "runtime_s"]


def pick(paths: list[Path], n: int | None) -> list[Path]:
    """``n`` maps spread evenly over the sorted list (all when ``n`` is None or too large)."""
    if n is None or n >= len(paths):
        return paths
    step = len(paths) / n
    return [paths[int(i * step)] for i in range(n)]


def map_seed(name: str, seed: int) -> int:
    return int(hashlib.sha256(f"{seed}:{name}".encode()).hexdigest()[:8], 16)


def r6(x):
    return "" if x is None else round(float(x), 6)


def one_map(path: Path, root: Path, config, solver: str, seed: int, grid, footprints) -> dict:
    from astropy.time import Time

    from mushrooms.evaluation.loop import loop_map
    from mushrooms.scheduler_core.sky.skymap import read_skymap

    name = str(path.relative_to(root)) if path.is_relative_to(root) else str(path)
    row = {"map": name}
    t0 = time.perf_counter()
    try:
        skymap = read_skymap(path, nside=config.nside)
        if skymap.event_time is None:
            return {**row, "status": "no event time"}
        out = loop_map(skymap, config, Time(skymap.event_time, scale="utc"), map_seed(name, seed), solver=solver,
                       grid=grid, footprints=footprints)
    except ValueError as exc:
        return {**row, "status": f"skipped: {exc}"[:120]}
    a, b, c = out.queue, out.loop, out.closure
    row.update(status="ok", night_start=out.plan.start.isot[:16], night_end=out.plan.end.isot[:16],
               closure_start=c.start.isot[:16], closure_end=c.end.isot[:16], closure_h=round(c.duration_s / 3600, 2),
               plan_exposures=len(out.plan.observations), plan_coverage=r6(out.plan.metrics.coverage),
               coverage_clear=r6(out.clear.coverage), coverage_cadence_clear=r6(out.clear.coverage_cadence),
               replan_exposures=len(out.replan.observations) if out.replan else 0, replan_repeats=out.repeats,
               done_a=a.n_done, done_b=b.n_done, coverage_a=r6(a.coverage), coverage_b=r6(b.coverage),
               coverage_gain=r6(b.coverage - a.coverage), coverage_cadence_a=r6(a.coverage_cadence),
               coverage_cadence_b=r6(b.coverage_cadence), detections_a=r6(a.expected_detections),
               detections_b=r6(b.expected_detections),
               detections_gain=(r6(b.expected_detections - a.expected_detections)
                                if a.expected_detections is not None else ""),
               night2_added_a=r6(a.night2_coverage), night2_added_b=r6(b.night2_coverage),
               # night 2 completes the pairs closer than the cadence (E3 with cadence_s): they count once, there
               two_nights_a=r6(a.coverage_cadence + a.night2_coverage),
               two_nights_b=r6(b.coverage_cadence + b.night2_coverage),
               runtime_s=round(time.perf_counter() - t0, 1))
    return row


def paired(rows: list[dict], a: str, b: str, tol: float) -> dict:
    """Means of two columns over the rows having both, the paired mean difference, its standard error, counts."""
    import numpy as np

    pairs = [(r[a], r[b]) for r in rows if r.get("status") == "ok" and r.get(a) != "" and r.get(b) != ""]
    if not pairs:
        return {"n": 0}
    x = np.array(pairs, float)
    d = x[:, 1] - x[:, 0]
    se = float(d.std(ddof=1) / math.sqrt(len(d))) if len(d) > 1 else float("nan")
    return {"n": len(d), "mean_a": x[:, 0].mean(), "mean_b": x[:, 1].mean(), "gain": d.mean(), "se": se,
            "better": int((d > tol).sum()), "worse": int((d < -tol).sum()), "same": int((abs(d) <= tol).sum())}


def summary(rows: list[dict], settings: str) -> str:
    ok = [r for r in rows if r.get("status") == "ok"]
    lines = [f"loop benchmark: {settings}",
             f"maps: {len(rows)} asked, {len(ok)} planned ({len(rows) - len(ok)} skipped: "
             + ", ".join(sorted({str(r['status']) for r in rows if r.get('status') != 'ok'})) + ")",
             "(a) original plan through the closure as the list queue; (b) re-planned at the reopening",
             f"{'metric':<38}{'n':>4}{'mean (a)':>11}{'mean (b)':>11}{'gain b-a':>11}{'± se':>10}"
             f"{'better':>8}{'worse':>7}{'same':>6}"]
    for label, a, b, tol in [("achieved coverage (night 1)", "coverage_a", "coverage_b", COV_TOL),
                             ("coverage, pairs >= cadence apart", "coverage_cadence_a", "coverage_cadence_b", COV_TOL),
                             ("expected detections (night 1)", "detections_a", "detections_b", DET_TOL),
                             ("night 2 added coverage", "night2_added_a", "night2_added_b", COV_TOL),
                             ("coverage after two nights (cadence)", "two_nights_a", "two_nights_b", COV_TOL)]:
        s = paired(rows, a, b, tol)
        if not s["n"]:
            lines.append(f"{label:<38}{0:>4}")
            continue
        lines.append(f"{label:<38}{s['n']:>4}{s['mean_a']:>11.5f}{s['mean_b']:>11.5f}{s['gain']:>+11.5f}"
                     f"{s['se']:>10.5f}{s['better']:>8}{s['worse']:>7}{s['same']:>6}")
    for label, col in [("plan's own coverage", "plan_coverage"), ("clear night, list queue", "coverage_clear"),
                       ("clear night, pairs >= cadence", "coverage_cadence_clear")]:
        vals = [float(r[col]) for r in ok]
        if vals:
            lines.append(f"{label:<38}{len(vals):>4}{sum(vals) / len(vals):>11.5f}   (no closure; reference)")
    rep = sum(int(r["replan_repeats"]) for r in ok)
    lines.append(f"better/worse beyond {COV_TOL:g} (coverage) and {DET_TOL:g} (detections); se = paired standard "
                 f"error of the mean gain; re-plan exposures in a pair done before the closure: {rep}")
    return "\n".join(lines)


def table(rows: list[dict]) -> str:
    head = (f"{'map':<52}{'closure (UTC)':>24}{'h':>5}{'cov a':>8}{'cov b':>8}{'gain':>9}{'det a':>9}{'det b':>9}"
            f"{'n2 a':>8}{'n2 b':>8}")
    out = [head]
    for r in rows:
        if r.get("status") != "ok":
            out.append(f"{r['map']:<52}  {r['status']}")
            continue
        det = lambda v: f"{v:>9.5f}" if v != "" else f"{'-':>9}"  # noqa: E731
        out.append(f"{r['map']:<52}{r['closure_start'][5:] + '-' + r['closure_end'][11:]:>24}{r['closure_h']:>5}"
                   f"{r['coverage_a']:>8.4f}{r['coverage_b']:>8.4f}{r['coverage_gain']:>+9.4f}"
                   f"{det(r['detections_a'])}{det(r['detections_b'])}{r['night2_added_a']:>8.4f}"
                   f"{r['night2_added_b']:>8.4f}")
    return "\n".join(out)


def figure(rows: list[dict], path: Path, settings: str) -> None:
    """Per-map coverage gain (b) - (a), sorted: pairs at any separation (left), pairs >= cadence apart (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    ok = [r for r in rows if r.get("status") == "ok"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6), sharex=True)
    for ax, (a, b, what) in zip(axes, [("coverage_a", "coverage_b", "pairs at any separation (Q6)"),
                                       ("coverage_cadence_a", "coverage_cadence_b", "pairs >= cadence apart")]):
        d = np.sort(np.array([r[b] - r[a] for r in ok], float))
        s = paired(rows, a, b, COV_TOL)
        colors = np.where(d > COV_TOL, "tab:green", np.where(d < -COV_TOL, "tab:red", "tab:gray"))
        ax.bar(np.arange(d.size), d, color=colors, width=0.8)
        ax.axhline(0, color="k", lw=0.8)
        if d.size:
            ax.axhline(s["gain"], color="tab:blue", ls="--", lw=1, label=f"mean {s['gain']:+.4f} ± {s['se']:.4f}")
            ax.legend(loc="upper left", fontsize=9, title=f"better {s['better']}, worse {s['worse']}, "
                      f"same {s['same']}", title_fontsize=9)
        ax.set_title(what, fontsize=10)
        ax.set_xlabel("sky map (sorted by gain)")
        ax.set_xlim(-1, max(d.size, 1))
    axes[0].set_ylabel("achieved coverage, re-plan (b) − list queue (a)")
    fig.suptitle(f"Re-planning at the reopening after a 1–3 h closure, night 1\n{settings}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", type=int, default=None, help="benchmark N maps spread over the list (default all)")
    ap.add_argument("--dir", default=str(MAPS), help="sky-map directory (default the shared maps)")
    ap.add_argument("--nside", type=int, default=128)
    ap.add_argument("--solver", default="greedy", help="scheduler of the original plan and the re-plans")
    ap.add_argument("--time-limit", type=float, default=None, help="time_limit_s of a MILP solver")
    ap.add_argument("--seed", type=int, default=28)
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args(argv)

    import dataclasses
    import logging

    from tqdm import tqdm

    from mushrooms.evaluation.bench.run import skymaps_in
    from mushrooms.offline import configure_astropy_offline
    from mushrooms.scheduler_core import PlanningConfig
    from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields

    configure_astropy_offline()
    logging.getLogger().setLevel(logging.WARNING)
    root = Path(args.dir)
    config = PlanningConfig(solver=args.solver, nside=args.nside)
    if args.time_limit is not None:
        config = dataclasses.replace(config, time_limit_s=args.time_limit)
    paths = pick(skymaps_in(root), args.maps)
    grid = load_ztf_fields()
    footprints = field_footprints(grid, config.nside)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    settings = (f"{len(paths)} maps, nside {config.nside}, solver {args.solver} (original and re-plans), "
                f"seed {args.seed}, cadence {config.cadence_s:g} s")
    t0 = time.perf_counter()
    rows = []
    bar = tqdm(paths, desc="loop", unit="map", file=sys.stderr)
    for p in bar:
        rows.append(one_map(p, root, config, args.solver, args.seed, grid, footprints))
        r = rows[-1]
        bar.set_postfix_str(f"{p.name}: {r['coverage_gain']:+.4f}" if r.get("status") == "ok" else p.name)
        write_rows(out / "loop_bench.csv", rows, COLUMNS)
    wall = time.perf_counter() - t0
    text = summary(rows, settings) + f"\nwall time {wall:.0f} s\n"
    (out / "loop_bench.txt").write_text(text + "\n" + table(rows) + "\n")
    figure(rows, out / "loop_gain.png", settings)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
