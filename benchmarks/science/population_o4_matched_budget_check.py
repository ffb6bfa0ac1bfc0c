"""Check every capped plan of the matched-budget rows with the checker under its capped study configuration.

    PYTHONPATH=$PWD /work/main/.venv/bin/python benchmarks/science/population_o4_matched_budget_check.py service_capped.jsonl.gz
"""
import gzip, json, dataclasses, sys
from collections import Counter
sys.path.insert(0, "/work/wt/cap55/benchmarks/science")
from population_o4_replan import settings_of
from pathlib import Path
import tempfile
from mushrooms.scheduler_core import check_plan, read_skymap
from mushrooms.scheduler_core.plan.document import Plan
R = Path("/work/wt/cap55/benchmarks/results/science/population_o4")
settings = settings_of(R / "study/config.toml", Path(tempfile.mkdtemp()))
recs = {json.loads(l)["map"]: json.loads(l)["skymap"] for l in gzip.open(R / "study/results.jsonl.gz", "rt")}
out = Counter()
from mushrooms.evaluation.bench.settings import keyed_row
for line in gzip.open(R / "matched_budget" / sys.argv[1], "rt"):
    d = json.loads(line)
    if not d["planned"]:
        continue
    keys = keyed_row(d["row"].removesuffix("-capped"))[1] or {}
    cfg = dataclasses.replace(settings.config, max_open_shutter_s=d["cap_s"], **{k: tuple(v) if isinstance(v, list) else v for k, v in keys.items()})
    plan = Plan.from_document(d["plan"])
    rep = check_plan(plan, read_skymap(recs[d["map"]], nside=cfg.nside), cfg)
    open_s = sum(o.exposure_s for o in plan.observations)
    out["ok" if rep.ok else "failed"] += 1
    print(d["map"][:24], "ok" if rep.ok else rep.problems[:2], f"open={open_s:.0f} cap={d['cap_s']:.0f}", flush=True)
print(dict(out))
