#!/usr/bin/env bash
# Issue 55, grgfix finding 1: the service under g-r-g at 180 s on o4real-0000-3 (44 deg2 BNS, 2012-02-19 12:44 UTC),
# the frozen run's localised map and configuration (read only), `mushrooms plan` of a checkout.
#   benchmarks/attacks/grgfix/o4real_0000_3_grg.sh TREE OUT_DIR
# Prints the answer, the windows of the likeliest fields (minutes from the start) and the plan's visits per field.
set -euo pipefail
tree=$(cd "$1" && pwd); out=$(mkdir -p "$2" && cd "$2" && pwd)
run=${RUN:-/work/population_o4_real}
map=$run/cache/maps/42ddcefc838353af-817cfa7aef2ca4da/3.fits
py=${PY:-/work/main/.venv/bin/python}
date -u; uptime; (cd "$tree" && git rev-parse HEAD 2>/dev/null || true)
for seq in '["g","r"]:300' '["g","r","g"]:180'; do
  f=${seq%%:*}; e=${seq##*:}; n=$(echo "$f" | tr -dc 'gr')
  (cd "$out" && PYTHONPATH="$tree" "$py" -m mushrooms.cli plan "$map" --config "$run/config.toml" \
     --set "scheduler.filters=$f" --set "scheduler.exposure_s=$e" --set scheduler.threads=1 -o "plan_$n.json" --brief) 2>&1 \
     | grep -v "^Running HiGHS\|^Includes third" || true
  PYTHONPATH="$tree" "$py" - "$out/plan_$n.json" <<'PY'
import json, sys
from collections import Counter
d = json.load(open(sys.argv[1]))
m = d["metrics"]
print(d["type"], {k: m.get(k) for k in ("coverage", "coverage_as_executed", "sequence_coverage_as_executed", "n_fields",
                                        "n_exposures", "solver")}, "best_coverage", d.get("best_coverage"))
print("visits per field:", sorted(Counter(Counter(o["field_id"] for o in d.get("observations", [])).values()).items()))
PY
done
PYTHONPATH="$tree" "$py" - "$map" <<'PY'
import sys
import numpy as np
from astropy.time import Time
from mushrooms.scheduler_core import PlanningConfig, prepare_problem, read_skymap
cfg = PlanningConfig(filters=("g", "r", "g"), exposure_s=180.0, threads=1)
p = prepare_problem(read_skymap(sys.argv[1], nside=cfg.nside), cfg, Time("2012-02-19T12:44:55.539", scale="utc"))
fp = p.footprints.field_probability(p.prob)
print("likeliest fields: probability, windows (min from the start, length); g-r-g at 180 s needs 63 min, g-r 33 min")
for k in np.argsort(-fp)[:8]:
    sel = p.windows.field_ids == p.field_ids[k]
    print(int(p.field_ids[k]), round(float(fp[k]), 4),
          [(round(s / 60, 1), round(e / 60, 1), round((e - s) / 60, 1)) for s, e in zip(p.windows.start[sel], p.windows.end[sel])])
PY
