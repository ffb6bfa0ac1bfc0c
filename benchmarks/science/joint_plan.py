"""Coordinated plan of two telescopes vs each alone, the uncoordinated union and the iterative tiling (issue 53 item 2).

Until the planner reads telescope descriptions (branch ``tel2``), two
telescopes are stood in for by ZTF problems on two field grids: ``A`` the
primary grid (ids < 1000) in g-r, 300 s, 30 min cadence; ``B`` the secondary
grid (ids >= 1000) in r-i, 240 s, 40 min cadence.  Both at Palomar, so they
compete for the same night's hours of the same sky: what coordination buys
is not covering the same probability twice.

For each map (its merger time as the start, 24 h horizon, work budget):

* ``alone A``, ``alone B``: each telescope's single-telescope plan (greedy, then the
  slot portfolio from it, ``time_limit_s`` work seconds);
* ``uncoordinated``: both plans alone, together (what two teams sharing a map do);
* ``tiling``: gwemopt's iterative tiling, A then B on what A left (``iterative_tiling``);
* ``coordinated``: ``joint_schedule`` (J6), with its certified bound (J8).

Union coverage (within the 24 h from the merger), the probability covered by both telescopes
(observed more than once), the time to 50 % of the probability (:func:`time_to_half`), the bound.

With ``--telescopes ztf,ls4`` (any two described telescopes) A and B are those; ``--all-shared`` runs
the 13 maps of :func:`shared_maps` (results in ``OUTDIR/all_shared/<a>_<b>`` when OUTDIR is given so).

    nice PYTHONPATH=. .venv/bin/python benchmarks/science/joint_plan.py [--limit 2] [--wide] [OUTDIR]
    nice PYTHONPATH=. .venv/bin/python benchmarks/science/joint_plan.py benchmarks/results/science/joint_plan/all_shared \
        --telescopes ztf,ls4 --all-shared
    nice PYTHONPATH=. .venv/bin/python benchmarks/science/joint_plan.py benchmarks/results/science/joint_plan/o4_real \
        --telescopes ztf,ls4 --localisations /work/population_o4_real/study/localisations.jsonl --prefix o4real
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from mushrooms.scheduler_core import PlanningConfig, read_skymap
from mushrooms.scheduler_core.prepare import prepare_problem
from mushrooms.scheduler_core.schedulers.joint import joint_metrics, joint_schedule
from mushrooms.scheduler_core.schedulers.joint.ascent import iterative_tiling
from mushrooms.scheduler_core.sky.fields import FieldGrid, load_ztf_fields

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path("/work/shared/data/skymaps")
MAPS = [
    ROOT / "tests/data/skymaps/MS220722v_bayestar.multiorder.fits",
    SHARED / "public/G483432_bayestar.multiorder.fits",
    SHARED / "public/S191216ap_bayestar.multiorder.fits",
    SHARED / "public/M403698_bayestar.multiorder.fits",
    SHARED / "simulated/bns_o3/2.fits",
    SHARED / "simulated/bns_o3/11.fits",
]
#: Wide maps (hundreds to thousands of deg²): two telescopes' nights are too short for them, coordination counts.
WIDE = [
    ROOT / "tests/data/skymaps/S200129m_cWB_RING.fits.gz",
    SHARED / "public/S200219ac_LALInference.fits.gz",
    SHARED / "public/GW170104_G268556_LALInference.fits",
    SHARED / "public/sim2015_coinc288830_bayestar_HV.fits.gz",
    SHARED / "public/S230627c_Bilby.multiorder.fits",
]
OUT = ROOT / "benchmarks/results/science/joint_plan"
#: A southern map (ZTF reaches 20 % of its probability, LS4 55 %): with described telescopes.
SOUTH = SHARED / "simulated/bns_o3/18.fits"


def shared_maps() -> list[Path]:
    """Shared maps: the six of MAPS, the southern one, three public O4 maps and three more of bns_o3."""
    extra = [SHARED / "public/S230518h_Bilby.offline0.multiorder.fits", SHARED / "public/S230731an_bayestar.multiorder.fits",
             SHARED / "public/S231113bw_Bilby.multiorder.fits", SHARED / "simulated/bns_o3/5.fits",
             SHARED / "simulated/bns_o3/7.fits", SHARED / "simulated/bns_o3/14.fits"]
    return MAPS + [SOUTH] + [p for p in extra if p.is_file()]


def population_maps(localisations: Path, prefix: str = "event") -> list[tuple[Path, str]]:
    """The sky maps a study localised (its ``localisations.jsonl``), named as its results name events
    (``PREFIX-CHUNK-COINC``: ``o4real`` for the ``o4-real`` recipe), in the order they were made."""
    out = []
    for line in localisations.read_text().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if rec.get("kind") == "result" and rec.get("ok") and Path(rec.get("path", "")).is_file():
            chunk = Path(rec["events"]).name.split(".")[0].split("-")[-1]
            out.append((Path(rec["path"]), f"{prefix}-{chunk}-{rec['coinc_id']}"))
    return out


def _grid(primary: bool) -> FieldGrid:
    g = load_ztf_fields()
    sel = (g.ids < 1000) if primary else (g.ids >= 1000)
    return FieldGrid(g.ids[sel], g.ra[sel], g.dec[sel])


def _configs(nside: int, limit: float, exposures: tuple[float, float] = (300.0, 240.0)
             ) -> tuple[PlanningConfig, PlanningConfig]:
    common = dict(solver="slots", nside=nside, time_limit_s=limit, detection_time_limit_s=min(0.5, limit / 2),
                  bound_time_limit_s=2.0, deterministic=True)
    return (PlanningConfig(exposure_s=exposures[0], **common),
            PlanningConfig(filters=("r", "i"), cadence_s=2400.0, exposure_s=exposures[1], **common))


def covered_times(problem, result) -> list[tuple[float, int]]:
    """(time s since the start, field id) at which each observed field becomes covered by its telescope's rule.

    The end of the field's ``k``-th exposure, ``k`` the number of filters of the
    planned sequence (ZTF's g-r pair: its second exposure; LS4's one ``i`` visit:
    that visit), or of its last exposure when it has fewer (not seen in these plans).
    """
    k = len(problem.config.filters)
    by_field: dict[int, list[float]] = {}
    for o in result.observations:
        by_field.setdefault(int(o.field_id), []).append(float(o.end))
    return [(sorted(ends)[min(k, len(ends)) - 1], f) for f, ends in by_field.items()]


def time_to_half(problems, results, prob: np.ndarray, fraction: float = 0.5) -> float | None:
    """Hours from the start (the merger) until the union of covered fields holds ``fraction`` of the map's probability.

    The fields of every telescope's plan in the order they become covered
    (:func:`covered_times`); the first time the probability inside the union of
    their footprints reaches ``fraction`` of the map's total (its sum, 1 for a
    normalised map, whatever the telescopes can see); None when it never does
    within the plans (24 h).
    """
    from mushrooms.scheduler_core.schedulers.joint.cells import covered_pixels

    events = sorted((t, i, f) for i, (p, r) in enumerate(zip(problems, results)) for t, f in covered_times(p, r))
    mask = np.zeros(prob.size, bool)
    total, target = 0.0, fraction * float(prob.sum())
    for t, i, f in events:
        pix = covered_pixels(problems[i], {f})
        total += float(prob[pix[~mask[pix]]].sum())
        mask[pix] = True
        if total >= target:
            return t / 3600.0
    return None


def _row(name: str, problems, results) -> dict:
    m = joint_metrics(problems, [{o.field_id for o in r.observations} for r in results], problems[0].prob)
    t50 = time_to_half(problems, results, problems[0].prob)
    return {"plan": name, "union": round(m.union, 4), "share_A": round(m.share[0], 4), "share_B": round(m.share[1], 4),
            "both": round(m.more_than_once, 4), "fields": [len({o.field_id for o in r.observations}) for r in results],
            "t50_h": None if t50 is None else round(t50, 3)}


def _described(skymap, start, nside: int, limit: float, names: tuple[str, str]) -> list:
    """The problems of two described telescopes (``--telescopes ztf,ls4``), each with its description's defaults."""
    from mushrooms.scheduler_core.instruments import load_description

    table = {"nside": nside, "time_limit_s": limit, "detection_time_limit_s": min(0.5, limit / 2),
             "bound_time_limit_s": 2.0, "deterministic": True}
    out = []
    for name in names:
        telescope = load_description(name)
        out.append(prepare_problem(skymap, PlanningConfig.for_telescope(telescope, table), start, telescope=telescope))
    return out


def one_map(path: Path, nside: int, limit: float, exposures: tuple[float, float] = (300.0, 240.0),
            telescopes: tuple[str, str] | None = None, name: str | None = None) -> dict | None:
    """Every plan of one map, as one JSON record (``telescopes``: two described telescopes instead of the grids)."""
    skymap = read_skymap(path, nside=nside)
    start = skymap.event_time
    if start is None:
        return None
    if telescopes is not None:
        problems = _described(skymap, start, nside, limit, telescopes)
    else:
        ca, cb = _configs(nside, limit, exposures)
        problems = [prepare_problem(skymap, ca, start, grid=_grid(True)),
                    prepare_problem(skymap, cb, start, grid=_grid(False))]
    t0 = time.perf_counter()
    joint = joint_schedule(problems, names=("A", "B"))
    wall_joint = time.perf_counter() - t0
    tiling = iterative_tiling(problems, problems[0].prob)
    tiling_ba = iterative_tiling(problems[::-1], problems[0].prob)[::-1]
    empty = type(joint.alone[0])((), "none", "none")
    rows = [_row("alone A", problems, [joint.alone[0], empty]), _row("alone B", problems, [empty, joint.alone[1]]),
            _row("uncoordinated", problems, list(joint.alone)), _row("tiling A>B", problems, tiling),
            _row("tiling B>A", problems, tiling_ba), _row("coordinated", problems, list(joint.schedules))]
    b = joint.bound
    if name is None:
        name = path.name if path.parent.name in ("public", "skymaps") else f"{path.parent.name}/{path.name}"
    return {"map": name,
            "start": start.isot, "candidates": [int(p.field_ids.size) for p in problems], "rows": rows,
            "method": joint.method, "bound": round(b.value, 4), "bound_joint": round(b.joint, 4) if np.isfinite(b.joint) else None,
            "bound_sum_u4": round(b.sum_of_telescopes, 4), "bound_total": round(b.total, 4),
            "bound_status": b.status, "exposures_s": list(exposures), "budget_work_s": joint.details["budget_s"],
            "spent_work_s": joint.details["spent_s"], "wall_joint_s": round(wall_joint, 1),
            "joint_model": joint.details.get("joint_model"), "ascent": joint.details.get("ascent")}


def _t50(v) -> str:
    return "never" if v is None else f"{v:.2f} h"


def _col(records: list[dict], name: str, key: str) -> list:
    return [[row.get(key) for row in r["rows"] if row["plan"] == name][0] for r in records]


def table(records: list[dict]) -> str:
    """The markdown table: one line per map and plan, then the means and paired differences."""
    lines = ["| map | plan | union | A's share | B's share | covered by both | time to 50 % | fields A, B |",
             "|---|---|---|---|---|---|---|---|"]
    for r in records:
        for row in r["rows"]:
            lines.append(f"| {r['map']} | {row['plan']} | {row['union']:.4f} | {row['share_A']:.4f} | "
                         f"{row['share_B']:.4f} | {row['both']:.4f} | {_t50(row.get('t50_h'))} | "
                         f"{row['fields'][0]}, {row['fields'][1]} |")
        bj = "not solved" if r["bound_joint"] is None else f"{r['bound_joint']:.4f}"
        lines.append(f"| {r['map']} | bound (J8) | {r['bound']:.4f} | B_joint {bj} | "
                     f"ΣU4 {r['bound_sum_u4']:.4f} | total {r['bound_total']:.4f} | | {r['method']} |")
    return "\n".join(lines + [""] + summary(records)) + "\n"


def summary(records: list[dict]) -> list[str]:
    """Means, medians and the coordinated plan's paired differences over the maps."""
    plans = [row["plan"] for row in records[0]["rows"]] if records else []
    n = len(records)
    lines = [f"Over {n} maps: means (medians), and the coordinated plan's paired difference (mean ± std. error; "
             "time to 50 %: median over the maps, never = after the 24 h; its paired difference over the maps "
             "where both reach 50 %):", "",
             "| plan | union mean (median) | covered by both mean (median) | reach 50 % | time to 50 % median | "
             "coordinated − plan (union) | coordinated − plan (time to 50 %, h) |", "|---|---|---|---|---|---|---|"]
    coord = np.array(_col(records, "coordinated", "union"))
    coord_t = _col(records, "coordinated", "t50_h")
    for name in plans:
        u, both = np.array(_col(records, name, "union")), np.array(_col(records, name, "both"))
        t = _col(records, name, "t50_h")
        d = coord - u
        se = d.std(ddof=1) / np.sqrt(d.size) if d.size > 1 else 0.0
        reach = [x for x in t if x is not None]
        med = np.median([np.inf if x is None else x for x in t]) if t else np.inf
        dt = np.array([a - b for a, b in zip(coord_t, t) if a is not None and b is not None])
        dts = (f"{dt.mean():+.2f} ± {dt.std(ddof=1) / np.sqrt(dt.size) if dt.size > 1 else 0.0:.2f} "
               f"(n {dt.size})") if dt.size else "no pair"
        lines.append(f"| {name} | {u.mean():.4f} ({np.median(u):.4f}) | {both.mean():.4f} ({np.median(both):.4f}) | "
                     f"{len(reach)} of {n} | {'never' if not np.isfinite(med) else f'{med:.2f} h'} | "
                     f"{d.mean():+.4f} ± {se:.4f} | {dts} |")
    bound = np.array([r["bound"] for r in records])
    lines.append(f"| bound (J8) | {bound.mean():.4f} ({np.median(bound):.4f}) | | | | "
                 f"gap to coordinated {np.mean(bound - coord):.4f} | |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", default=str(OUT))
    ap.add_argument("--nside", type=int, default=128)
    ap.add_argument("--limit", type=float, default=2.0, help="each telescope's time_limit_s (work s)")
    ap.add_argument("--maps", type=int, default=None, help="the first N maps only")
    ap.add_argument("--wide", action="store_true", help="the wide maps instead (results in OUTDIR/wide)")
    ap.add_argument("--telescopes", default=None, help="two described telescopes, e.g. ztf,ls4 (results in "
                    "OUTDIR/<a>_<b>): A and B are those, each with its description's defaults")
    ap.add_argument("--exposures", default="300,240", help="A's and B's exposure (s); other than the default: "
                    "results in OUTDIR/exposures_A_B")
    ap.add_argument("--all-shared", action="store_true", help="every map of the shared set (shared_maps)")
    ap.add_argument("--localisations", type=Path, default=None,
                    help="a study's localisations.jsonl: its sky maps instead (a simulated population's events)")
    ap.add_argument("--prefix", default="event", help="event names PREFIX-CHUNK-COINC (the o4-real study's: o4real)")
    args = ap.parse_args(argv)
    exposures = tuple(float(x) for x in args.exposures.split(","))
    sub = "" if exposures == (300.0, 240.0) else f"exposures_{exposures[0]:g}_{exposures[1]:g}"
    telescopes = tuple(args.telescopes.split(",")) if args.telescopes else None
    if telescopes:
        sub = "_".join(telescopes)
    out = Path(args.out) / ("wide" if args.wide else "") / sub
    maps = (WIDE if args.wide else MAPS) + ([SOUTH] if telescopes and not args.wide else [])
    if args.all_shared:
        maps = shared_maps()
    names = {}
    if args.localisations is not None:
        named = population_maps(args.localisations, args.prefix)
        maps, names = [p for p, _ in named], {p: n for p, n in named}
    out.mkdir(parents=True, exist_ok=True)
    load0 = os.getloadavg()
    records = []
    with open(out / "joint_plan.jsonl", "w") as f:
        for path in maps[:args.maps] if args.maps else maps:
            rec = one_map(path, args.nside, args.limit, exposures, telescopes, names.get(path))
            if rec is None:
                print(path.name, "skipped: no event time in the map", flush=True)
                continue
            records.append(rec)
            f.write(json.dumps(rec) + "\n")
            f.flush()
            print(rec["map"], [(r["plan"], r["union"], r["both"]) for r in rec["rows"]], "bound", rec["bound"],
                  rec["method"], f"{rec['wall_joint_s']} s", flush=True)
    load1 = os.getloadavg()
    what = (f"A = {telescopes[0]}, B = {telescopes[1]} (their descriptions' defaults)" if telescopes
            else f"exposures A {exposures[0]:g} s, B {exposures[1]:g} s")
    head = (f"nside {args.nside}, {what}, "
            f"time_limit_s {args.limit} work s per telescope (joint budget 3 x the sum), "
            f"deterministic budget; load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end\n\n")
    (out / "joint_plan.md").write_text(head + table(records))
    print(head + table(records))
    return 0


if __name__ == "__main__":
    sys.exit(main())
