"""The service's parts alone vs around ZTF's revision (issue 53 items 2 + 4, ``docs/design/telescopes.md`` J9).

For each map: ZTF's revision 1 as the service plans it (the fast scheduler,
ZTF's default configuration at ``--nside``, from the map's event time), then
every other telescope's part two ways: **alone** (main before J9:
``handlers.telescope_plans.plan_alone``, each telescope's fast plan on the
whole map) and **around** (J9: ``scheduler_core.joint_parts.plan_around``,
ZTF's revision held fixed, each telescope in order on the sky left).  The
joint metrics of ZTF's revision with each set of parts (``joint_metrics``,
the planner's footprints), the bound J8 of the joint document, and the
wall time of the parts (quote it with the load).

    python benchmarks/science/service_parts.py --telescopes ls4 --nside 64 --out DIR
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks" / "science"))

from joint_plan import MAPS, SOUTH  # noqa: E402  the shared maps of the joint plan's benchmark


def one_map(path: Path, names: list[str], nside: int) -> dict:
    from mushrooms.handlers.telescope_plans import plan_alone, prepare_telescopes
    from mushrooms.scheduler_core import PlanningConfig, not_observable, read_skymap
    from mushrooms.scheduler_core.anytime import first_plan
    from mushrooms.scheduler_core.instruments import load_description
    from mushrooms.scheduler_core.joint_parts import Held, around_document, around_key, fields_of, plan_around
    from mushrooms.scheduler_core.plan.document import Plan
    from mushrooms.scheduler_core.prepare import prepare_problem
    from mushrooms.scheduler_core.schedulers.joint.cells import joint_metrics

    skymap = read_skymap(path.read_bytes(), nside=nside)
    start = skymap.event_time
    table = {"nside": nside, "solver": "greedy", "deterministic": True}
    ztf_cfg = PlanningConfig.from_mapping(table)
    zp = prepare_problem(skymap, ztf_cfg, start)
    ztf = first_plan(zp, skymap)
    ztf = ztf if not_observable(ztf, skymap, ztf_cfg) is None else not_observable(ztf, skymap, ztf_cfg)
    zdoc = ztf.to_document() if isinstance(ztf, Plan) else None
    runs = [(t, PlanningConfig.for_telescope(t, table)) for t in map(load_description, names)]
    t0 = time.perf_counter()
    alone = {t.name: plan_alone(skymap, t, c, start) for t, c in runs}
    t_alone = time.perf_counter() - t0
    t0 = time.perf_counter()
    problems = prepare_telescopes(skymap, runs, start)
    held = [Held("ztf", zp, fields_of(zdoc))]
    key = around_key([("ztf", ztf.plan_id, held[0].fields)])
    around = plan_around(skymap, held, [(n, problems[n]) for n in names], key)
    entries = [("ztf", zp, zdoc, "exported" if zdoc else "not_observable")] + [
        (n, problems[n], around[n].to_document() if isinstance(around[n], Plan) else None, "x") for n in names]
    doc = around_document(entries, zp.prob)
    t_around = time.perf_counter() - t0
    all_problems = [zp] + [problems[n] for n in names]

    def metrics(parts: dict) -> dict:
        fields = [set(fields_of(zdoc))] + [set(fields_of(parts[n].to_document())) if isinstance(parts[n], Plan)
                                           else set() for n in names]
        m = joint_metrics(all_problems, fields, zp.prob)
        return {"union": round(m.union, 6), "twice": round(m.more_than_once, 6),
                "share": [round(s, 6) for s in m.share]}

    return {"map": path.name if path.parent.name in ("public", "skymaps") else f"{path.parent.name}/{path.name}",
            "ztf": round(float(ztf.metrics.coverage), 6) if zdoc else 0.0, "alone": metrics(alone),
            "around": metrics(around), "bound": doc["metrics"]["upper_bound"],
            "bound_status": doc["metrics"]["upper_bound_status"], "parts_s_alone": round(t_alone, 2),
            "parts_s_around": round(t_around, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--telescopes", default="ls4", help="the other telescopes, in order (comma-separated)")
    ap.add_argument("--nside", type=int, default=64)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--maps", type=int, default=None, help="the first N maps only")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    names = args.telescopes.split(",")
    rows = []
    for path in [p for p in MAPS + [SOUTH] if p.is_file()][:args.maps]:
        row = one_map(path, names, args.nside)
        rows.append(row)
        print(json.dumps(row), flush=True)
    tag = "_".join(names) + f"_nside{args.nside}"
    (args.out / f"{tag}.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    lines = [f"# ZTF revision 1 (greedy) + {', '.join(names)}: parts alone vs around ZTF (J9), nside {args.nside}",
             f"# load {os.getloadavg()[0]:.1f} at the end (2 cores)", "",
             "| map | ZTF | union alone | union around | twice alone | twice around | bound | parts s alone | "
             "parts s around |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['map']} | {r['ztf']:.4f} | {r['alone']['union']:.4f} | {r['around']['union']:.4f} | "
                     f"{r['alone']['twice']:.4f} | {r['around']['twice']:.4f} | {r['bound']:.4f} | "
                     f"{r['parts_s_alone']} | {r['parts_s_around']} |")
    n = len(rows)
    du = [r["around"]["union"] - r["alone"]["union"] for r in rows]
    dt = [r["around"]["twice"] - r["alone"]["twice"] for r in rows]
    lines += ["", f"n = {n}: union around - alone mean {sum(du) / n:+.4f} (min {min(du):+.4f}, max {max(du):+.4f}); "
                  f"twice around - alone mean {sum(dt) / n:+.4f} (min {min(dt):+.4f}, max {max(dt):+.4f})"]
    (args.out / f"{tag}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
