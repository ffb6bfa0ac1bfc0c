#!/usr/bin/env bash
# Side-by-side wall time of `mushrooms plan` with the default config vs --solver greedy:
# per map one run each, alternating, imports included; run it with the machine quiet.
#   benchmarks/plan_wall_side_by_side.sh            (maps from $SKYMAPS, default ../shared/data/skymaps)
#   benchmarks/plan_wall_side_by_side.sh MAP...     (these maps instead)
#   ARM_CONFIG=FILE benchmarks/plan_wall_side_by_side.sh ...   (a third run per map: the default with --config FILE,
#                                                              e.g. one setting [scheduler] exposure_menu_s; row "config")
# Each run's stage-times log line (`times: ...`) is printed after its row.
set -u
cd "$(dirname "$0")/.."
data=${SKYMAPS:-$(cd .. && pwd)/shared/data/skymaps}
out=$(mktemp -d)
maps=(tests/data/skymaps/MS220722v_bayestar.multiorder.fits $data/public/G483432_bayestar.multiorder.fits $data/public/S191216ap_bayestar.multiorder.fits $data/public/M403698_bayestar.multiorder.fits $data/simulated/bns_o3/2.fits $data/simulated/bns_o3/14.fits $data/simulated/nsbh_o3/allsky_400to799/1.fits $data/simulated/nsbh_o3/allsky_400to799/8.fits)
[ $# -gt 0 ] && maps=("$@")
py=${PYTHON:-.venv/bin/python}
for m in "${maps[@]}"; do
  n=$(basename $(dirname $m))_$(basename $m .fits)
  arms=(greedy default); [ -n "${ARM_CONFIG:-}" ] && arms+=(config)
  for s in "${arms[@]}"; do
    opt=(); [ $s = greedy ] && opt=(--solver greedy); [ $s = config ] && opt=(--config "$ARM_CONFIG")
    t0=$(date +%s.%N); $py -m mushrooms.cli plan "$m" "${opt[@]}" -o $out/t_$s.json > $out/t_$s.log 2>&1; rc=$?; t1=$(date +%s.%N)
    python3 -c "
import json; d=json.load(open('$out/t_$s.json')); m=d['metrics']
print('$n', '$s', round($t1-$t0,2), 'rc=$rc', m['solver'], m['coverage'], m.get('upper_bound'), m.get('upper_bound_method'), m['runtime_s'])"
    grep -o 'times: .*' $out/t_$s.log | sed 's/^/    /'
  done
done
uptime
