#!/usr/bin/env bash
# Behaviour of one checkout for a refactor's before/after: the demo plan,
# five shared maps planned with greedy and with the hybrid, and the replay of the
# MS181101ab notice sequence (greedy and default config), every document kept.
#   benchmarks/identity/refactor_identity.sh TREE OUT_DIR
# SOLVERS (default "greedy hybrid") names the --solver runs on the five maps.
# TREE is a checkout (its package is put first on sys.path); the venv is /work/main/.venv
# unless $PY names another interpreter. Compare two OUT_DIRs with refactor_compare.py.
set -euo pipefail
tree=$(cd "$1" && pwd); out=$(mkdir -p "$2" && cd "$2" && pwd)
py=${PY:-/work/main/.venv/bin/python}
data=/work/shared/data/skymaps
maps=(
  "$tree/tests/data/skymaps/MS220722v_bayestar.multiorder.fits"
  "$data/public/G483432_bayestar.multiorder.fits"
  "$data/public/S191216ap_bayestar.multiorder.fits"
  "$data/public/M403698_bayestar.multiorder.fits"
  "$data/simulated/bns_o3/2.fits"
)
run() { (cd "$tree" && PYTHONPATH="$tree" "$py" -m mushrooms.cli "$@"); }
printf '[scheduler]\nsolver = "greedy"\n' > "$out/greedy.toml"
printf '[export]\nskyportal_allocation_id = 7\n' > "$out/plan.toml"
[ -n "${ONLY_PLANS:-}" ] || run demo --out "$out/demo" --config "$out/greedy.toml" > "$out/demo_greedy.log" 2>&1
[ -n "${ONLY_PLANS:-}" ] || run demo --out "$out/demo_default" > "$out/demo_default.log" 2>&1
for m in "${maps[@]}"; do
  n=$(basename "$m"); n=${n%%.*}
  for s in ${SOLVERS:-greedy hybrid}; do
    run plan "$m" --solver "$s" -o "$out/plan_${n}_${s}.json" --queue "$out/queue_${n}_${s}.json" \
        --skyportal "$out/skyportal_${n}_${s}.json" --config "$out/plan.toml" > "$out/plan_${n}_${s}.log" 2>&1 || echo "exit $? $n $s" >> "$out/failures.txt"
  done
done
notices="$tree/tests/data/notices/json"
seq=(MS181101ab-earlywarning MS181101ab-preliminary MS181101ab-initial MS181101ab-update MS181101ab-ext-update MS181101ab-retraction)
files=(); for s in "${seq[@]}"; do files+=("$notices/$s.json"); done
[ -n "${ONLY_PLANS:-}" ] || run replay --allow-mock --out "$out/replay_greedy" --config "$out/greedy.toml" "${files[@]}" > "$out/replay_greedy.log" 2>&1
[ -n "${ONLY_PLANS:-}" ] || run replay --allow-mock --out "$out/replay_default" "${files[@]}" > "$out/replay_default.log" 2>&1
echo "done $out"
