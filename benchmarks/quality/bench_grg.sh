#!/usr/bin/env bash
# The four strategies of the default decision, paired on the same maps and injections: fixed 300 s (hybrid),
# fixed 180 s (hybrid@e180), the exposure menu (hybrid@menu, 180 s in it), and ZTF's O4 practice g-r-g at
# 180 s with a 30 min cadence (hybrid@grg, gwemopt's --filters g,r,g --exposuretimes 180,180,180 --mindiff 30),
# planned by the hybrid (greedy + slot/block MILP on the sequence, F4).  Maps: a fixed subset of the shared
# maps with distance layers (public/, simulated/bns_o3, simulated/nsbh_o3), every STRIDE-th in name order
# (STRIDE 1: all 52); nside 128, threads 1, 10 000 injections, config beside the results.
#   benchmarks/quality/bench_grg.sh RESULTS_DIR [SOLVERS] [LOAD]
# SOLVERS default hybrid,hybrid@e180,hybrid@menu,hybrid@grg; LOAD=busy starts BUSY (default 2) busy loops
# beside the two jobs (two plans at once plus the loops: a load of 4 on 2 cores of this run's own), at the
# plans' nice level, and ends them after.  Everything runs under nice 10; uptime is logged every minute.
set -eu
cd "$(dirname "$0")/../.."
res=$1; solvers=${2:-hybrid,hybrid@e180,hybrid@menu,hybrid@grg}; load=${3:-quiet}
data=${SKYMAPS:-/work/shared/data/skymaps}; stride=${STRIDE:-2}
py=${PYTHON:-/work/main/.venv/bin/python}
maps=$res/maps; mkdir -p "$maps"
"$py" - "$data" "$maps" "$stride" <<'PY'
import os, sys
from pathlib import Path
from astropy.io import fits
root, out, stride = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
found = []
for sub in ("public", "simulated/bns_o3", "simulated/nsbh_o3"):  # the maps with distance layers
    for p in sorted((root / sub).rglob("*")):
        if p.name.endswith((".fits", ".fits.gz")):
            with fits.open(p) as h:
                if "DISTMU" in [c.upper() for c in h[1].columns.names]:
                    found.append((f"{sub.replace('/', '_')}__{p.relative_to(root / sub).as_posix().replace('/', '__')}", p))
for name, p in sorted(found)[::stride]:
    if not (out / name).exists():
        os.symlink(p, out / name)
print(f"{len(sorted(found)[::stride])} of {len(found)} maps (every {stride}th in name order)")
PY
[ -f "$res/config.toml" ] || printf '# g-r-g default bench: default [scheduler] except nside 128 and threads 1\n[scheduler]\nnside = 128\nthreads = 1\n' > "$res/config.toml"
busy=""
if [ "$load" = busy ]; then
  for _ in $(seq "${BUSY:-2}"); do nice -n 10 bash -c 'while :; do :; done' & busy="$busy $!"; done
fi
trap '[ -n "$busy" ] && kill $busy' EXIT
(uptime; date -u) > "$res/uptime_start.txt"
PYTHONPATH=$(pwd) MUSHROOMS_PROGRESS=0 nice -n 10 "${MUSHROOMS:-/work/main/.venv/bin/mushrooms}" bench "$maps" --config "$res/config.toml" --solvers "$solvers" \
  --arm 'e180:exposure_s=180' --arm 'menu:exposure_menu_s=[30,60,120,180,300,600]' \
  --arm 'grg:filters=["g","r","g"]' --arm 'grg:exposure_s=180' --arm 'grg:cadence_s=1800' \
  --jobs 2 -o "$res/results.csv" > "$res/summary.txt" 2> "$res/stderr.txt" &
bench=$!
while kill -0 $bench 2>/dev/null; do uptime >> "$res/uptime_during.txt"; sleep 60; done
wait $bench; echo "exit $?" >> "$res/summary.txt"
(uptime; date -u) > "$res/uptime_end.txt"
