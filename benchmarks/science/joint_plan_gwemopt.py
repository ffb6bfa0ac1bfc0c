"""gwemopt 0.4.2 with ZTF and DECam, scored by the joint plan's rule (issue 53 item 3).

gwemopt plans several telescopes one after the other (``gwemopt/coverage.py``
``powerlaw`` 134-360, a loop over ``params["telescopes"]``); with
``--doIterativeTiling`` (``args.py:38``) each telescope after the first should
plan on what the earlier ones left (``coverage.py:355-356`` calls
``tiles.slice_map_tiles``).  In 0.4.2 with MOC tiles that call raises
``KeyError: 'prob'`` (``tiles.py:24`` reads ``map_struct["prob"]``, a key the
0.4.2 map reader, ``io/skymap.py:285-324``, no longer writes), and the next
telescope's tile probabilities are read from ``map_struct["skymap_schedule"]``
(``tiles.py:806-818``, through ``schedule_alternating`` 469-518), which the
slice never touches: gwemopt's iterative tiling cannot be run as shipped
(``benchmarks/results/science/joint_plan/gwemopt/iterative_crash/``).  What runs
is the same line without it: each telescope plans the whole map, which is what
SkyPortal's combined plans do (issue 53), i.e. gwemopt's uncoordinated plan.

The command (``launcher.py`` beside the results turns IERS downloads off, then
``gwemopt.run.run``), each option in gwemopt 0.4.2's ``args.py``:
``--telescopes ZTF,DECam`` (65; ``data/config/ZTF.config``, ``DECam.config``,
tessellations ``ZTF.tess``, ``DECam.tess``; gwemopt ships no LS4), ``--doTiles
--tilesType moc`` (34-35), ``--doSchedule --scheduleType greedy`` (22-23),
``--timeallocationType powerlaw`` (25), ``--filters g,r --exposuretimes 300,300``
(109, 116: one filter list for every telescope, ``params.py:104-105``),
``--doSingleExposure --doAlternatingFilters`` (as the project's ZTF baseline,
``mushrooms/evaluation/gwemopt_options.py``), ``--nside 128 --airmass 2.5``,
``--gpstime`` the merger, ``--Tobs 0,1`` (24 h); in ``skyportal_form/`` SkyPortal's plan-form options
instead (``gwemopt-skyportal`` of ``gwemopt_options.py``: ``--filters g,r,g --exposuretimes 300,300,300
--doBalanceExposure --doUsePrimary --airmass 2.0``).  The runs are shell lines (``args.txt`` beside each
result); this module scores what they wrote.

Scoring (the same pair rule and union as ``joint_plan.py``): a field of a
telescope is covered when two of its exposures in different filters start at
least ``cadence_s`` (1800 s, both descriptions) apart, at the end of the later;
ZTF's fields are ZTF grid ids (our footprints, 16 CCDs); DECam's pointings are
gwemopt's ``DECam.tess`` centres, footprinted with our DECam description's
detectors.  gwemopt's exposures are not checked against our windows (twilight,
airmass, Moon): the score is what gwemopt plans, not what our checker accepts.  Rule ``once``
as well: a field covered at the end of its first exposure (the probability observed at least once).

    nice PYTHONPATH=. .venv/bin/python benchmarks/science/joint_plan_gwemopt.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from astropy.time import Time

from mushrooms.scheduler_core import PlanningConfig, read_skymap
from mushrooms.scheduler_core.instruments import load_description
from mushrooms.scheduler_core.instruments.active import covering_polygons
from mushrooms.scheduler_core.sky.fields import Camera, FieldGrid, field_footprints, load_ztf_fields

ROOT = Path(__file__).resolve().parents[2]
SHARED = Path("/work/shared/data/skymaps")
OUT = ROOT / "benchmarks/results/science/joint_plan/gwemopt"
RUNS = {"MS220722v": ROOT / "tests/data/skymaps/MS220722v_bayestar.multiorder.fits",
        "G483432": SHARED / "public/G483432_bayestar.multiorder.fits",
        "bns_o3_18": SHARED / "simulated/bns_o3/18.fits", "bns_o3_2": SHARED / "simulated/bns_o3/2.fits"}
#: Their names in ``all_shared/ztf_decam/joint_plan.jsonl``.
JOINT_NAMES = {"MS220722v": "MS220722v_bayestar.multiorder.fits", "G483432": "G483432_bayestar.multiorder.fits",
               "bns_o3_18": "bns_o3/18.fits", "bns_o3_2": "bns_o3/2.fits"}
NSIDE = 128
CADENCE_S = 1800.0


def read_schedule(path: Path, start: Time) -> list[dict]:
    """gwemopt's ``schedule_<telescope>.dat``: field, ra, dec, start (s since ``start``), exposure (s), filter."""
    out = []
    for line in path.read_text().splitlines():
        r = line.split()
        if len(r) < 9 or line.startswith("#"):
            continue
        out.append({"field": int(float(r[0])), "ra": float(r[1]), "dec": float(r[2]),
                    "t": (float(r[3]) - start.mjd) * 86400.0, "texp": float(r[5]), "filter": r[8]})
    return out


def pair_times(rows: list[dict], rule: str = "pair") -> dict[int, float]:
    """Field -> the end of the exposure that completes its pair (two filters >= CADENCE_S apart).

    ``rule = "once"``: the end of its first exposure (observed at least once, no pair asked).
    """
    by: dict[int, list[dict]] = {}
    for r in sorted(rows, key=lambda r: r["t"]):
        by.setdefault(r["field"], []).append(r)
    if rule == "once":
        return {f: exps[0]["t"] + exps[0]["texp"] for f, exps in by.items()}
    done = {}
    for f, exps in by.items():
        for k, late in enumerate(exps):
            if any(e["filter"] != late["filter"] and late["t"] - e["t"] >= CADENCE_S for e in exps[:k]):
                done[f] = late["t"] + late["texp"]
                break
    return done


def footprints_of(telescope: str, rows: list[dict]):
    """Pixels of each scheduled field: ZTF's grid footprints, or DECam's detectors at gwemopt's centres."""
    if telescope == "ZTF":
        return field_footprints(load_ztf_fields(), NSIDE)
    decam = load_description("decam")
    ids = sorted({r["field"] for r in rows})
    centre = {r["field"]: (r["ra"], r["dec"]) for r in rows}
    grid = FieldGrid(np.array(ids, int), np.array([centre[i][0] for i in ids]), np.array([centre[i][1] for i in ids]))
    camera = Camera(covering_polygons(decam, tuple(decam.planning.filters)), decam.footprint.radius_deg)
    return field_footprints(grid, NSIDE, camera)


def score(name: str, path: Path, base: Path = OUT, rule: str = "pair") -> dict | None:
    """Union within 24 h, each telescope's share, covered more than once, time to 50 % of gwemopt's plan.

    ``base / name / out`` holds gwemopt's schedules; ``rule``: ``pair`` (the joint plan's) or ``once``.
    """
    skymap = read_skymap(path, nside=NSIDE)
    start, prob = skymap.event_time, skymap.prob
    events, count, share, exposures = [], np.zeros(prob.size, np.int32), {}, {}
    for tel in ("ZTF", "DECam"):
        f = base / name / "out" / f"schedule_{tel}.dat"
        if not f.is_file():
            return None
        rows = read_schedule(f, start)
        exposures[tel] = len(rows)
        done = {k: t for k, t in pair_times(rows, rule).items() if t <= 86400.0}
        fp = footprints_of(tel, rows) if done else None
        pix = fp.union(list(done)) if done else np.zeros(0, int)
        count[pix] += 1
        share[tel] = round(float(prob[pix].sum()), 4)
        events += [(t, fp.pixels(k)) for k, t in done.items()]
    mask, total, t50 = np.zeros(prob.size, bool), 0.0, None
    for t, pix in sorted(events, key=lambda e: e[0]):
        total += float(prob[pix[~mask[pix]]].sum())
        mask[pix] = True
        if t50 is None and total >= 0.5 * float(prob.sum()):
            t50 = round(t / 3600.0, 3)
    return {"map": JOINT_NAMES[name], "union": round(float(prob[count > 0].sum()), 4), "share": share,
            "more_than_once": round(float(prob[count > 1].sum()), 4), "t50_h": t50, "exposures": exposures,
            "covered_fields": int(len(events)), "rule": rule, "variant": base.name}


def _ours(rows: dict, name: str) -> list[str]:
    """The joint plan benchmark's rows of one map (pair rule)."""
    out = []
    for plan in ("uncoordinated", "tiling A>B", "coordinated"):
        row = rows.get(plan)
        if row:
            t = "never" if row.get("t50_h") is None else f"{row['t50_h']:.2f} h"
            out.append(f"| {name} | mushrooms {plan} (pair rule) | {row['union']:.4f} | {row['share_A']:.4f} | "
                       f"{row['share_B']:.4f} | {row['both']:.4f} | {t} |")
    return out


def main() -> int:
    joint = {}
    jl = OUT.parent / "all_shared/ztf_decam/joint_plan.jsonl"
    if jl.is_file():
        for line in jl.read_text().splitlines():
            r = json.loads(line)
            joint[r["map"]] = {row["plan"]: row for row in r["rows"]} | {"bound": r["bound"]}
    lines = ["| map | plan | union (24 h) | ZTF's share | DECam's share | more than once | time to 50 % |",
             "|---|---|---|---|---|---|---|"]
    records = []
    for name, path in RUNS.items():
        for base, label in ((OUT, "greedy, g,r"), (OUT / "skyportal_form", "SkyPortal form")):
            for rule in ("pair", "once"):
                rec = score(name, path, base, rule)
                if rec is None:
                    continue
                records.append(rec)
                t = "never" if rec["t50_h"] is None else f"{rec['t50_h']:.2f} h"
                lines.append(f"| {rec['map']} | gwemopt ZTF,DECam ({label}; {rule} rule) | {rec['union']:.4f} | "
                             f"{rec['share']['ZTF']:.4f} | {rec['share']['DECam']:.4f} | {rec['more_than_once']:.4f} "
                             f"| {t} |")
        lines += _ours(joint.get(JOINT_NAMES[name], {}), JOINT_NAMES[name])
    (OUT / "gwemopt_scored.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    (OUT / "gwemopt_scored.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
