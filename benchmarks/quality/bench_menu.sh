#!/usr/bin/env bash
# `mushrooms bench` rows for fixed 300 s vs the exposure menu: the default plan (hybrid) and
# the plan published under the same config with [scheduler] exposure_menu_s = [30, 60, 120, 300, 600]
# (hybrid@menu), and the same menu with the detection stage given 8 s instead of 4 s on top of the scheduler's
# 10 s (hybrid@menu8: time_limit_s 18, detection_time_limit_s 8), paired on the same maps and injections, on
# every shared map with distance layers
# (public/, simulated/bns_o3, simulated/nsbh_o3; 52 maps), nside 128, threads 1 (config beside the results).
#   benchmarks/quality/bench_menu.sh [JOBS]       (maps from $SKYMAPS, default ../shared/data/skymaps; JOBS default 2)
#   RESULTS=DIR benchmarks/quality/bench_menu.sh    (results in DIR instead of benchmarks/results/quality/bench_menu)
# Expected detections and efficiencies of these clock-limited solves depend on the machine's load: say it.
set -eu
cd "$(dirname "$0")/../.."
data=${SKYMAPS:-$(cd .. && pwd)/shared/data/skymaps}
res=${RESULTS:-benchmarks/results/quality/bench_menu}
maps=$(mktemp -d)
.venv/bin/python - "$data" "$maps" <<'PY'
import os, sys
from pathlib import Path
from astropy.io import fits
root, out = Path(sys.argv[1]), Path(sys.argv[2])
for sub in ("public", "simulated/bns_o3", "simulated/nsbh_o3"):  # the maps with distance layers
    for p in sorted((root / sub).rglob("*")):
        if p.name.endswith((".fits", ".fits.gz")):
            with fits.open(p) as h:
                if "DISTMU" in [c.upper() for c in h[1].columns.names]:
                    rel = p.relative_to(root / sub).as_posix().replace("/", "__")
                    os.symlink(p, out / f"{sub.replace('/', '_')}__{rel}")
PY
mkdir -p $res; [ -f $res/config.toml ] || printf "# exposure-menu bench rows: default [scheduler] except nside 128 and threads 1\n[scheduler]\nnside = 128\nthreads = 1\n" > $res/config.toml
uptime | tee $res/uptime_start.txt
MUSHROOMS_PROGRESS=0 .venv/bin/mushrooms bench "$maps" --config $res/config.toml --solvers hybrid,hybrid@menu,hybrid@menu8 \
  --arm 'menu:exposure_menu_s=[30,60,120,300,600]' --arm 'menu8:exposure_menu_s=[30,60,120,300,600]' \
  --arm 'menu8:detection_time_limit_s=8.0' --arm 'menu8:time_limit_s=18.0' --jobs "${1:-2}" --plots $res -o $res/results.csv | tee $res/summary.txt
uptime | tee $res/uptime_end.txt
