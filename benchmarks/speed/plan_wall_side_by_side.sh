#!/usr/bin/env bash
# `mushrooms plan` side by side on two source trees: per map, greedy and the default config on each tree,
# the tree that goes first alternating per map (a slow spell of a shared machine falls on both); imports included.
#
#   benchmarks/speed/plan_wall_side_by_side.sh BASE_TREE NEW_TREE [MAP...]
#       every *.fits / *.fits.gz under $SKYMAPS (default /work/shared/data/skymaps: public + simulated) unless
#       maps are given; REPEAT=N greedy runs per map and tree (default 3: the median is the map's greedy wall);
#       OUT=FILE the raw rows (default benchmarks/results/speed/plan_wall_side_by_side.txt); the summary table
#       (benchmarks/speed/plan_wall_summary.py --trees) goes beside it as FILE.summary.txt.
#   benchmarks/speed/plan_wall_side_by_side.sh                (one tree, this one: the old greedy vs default rows)
#
# A base tree: git -C /work/wt/speed worktree add --detach /work/wt/speed-base 0f793b0
# Each tree runs as `PYTHONPATH=TREE $PYTHON -m mushrooms.cli plan ...` (PYTHON default /work/main/.venv/bin/python).
# Row: tree map arm wall rc solver coverage bound bound_method runtime_s expected_detections coverage_as_executed
# budget_spent budget_kind budget_interrupted (metrics.budget: work seconds under [scheduler] deterministic = true);
# each run's stage-times log line (`times: ...`) follows its row.  Run it with the machine quiet; the load is
# printed every map.
set -u
here=$(cd "$(dirname "$0")/../.." && pwd)
py=${PYTHON:-/work/main/.venv/bin/python}
data=${SKYMAPS:-/work/shared/data/skymaps}
repeat=${REPEAT:-3}
if [ $# -ge 2 ] && [ -d "$1/mushrooms" ] && [ -d "$2/mushrooms" ]; then
  trees=("$(cd "$1" && pwd)" "$(cd "$2" && pwd)"); shift 2
else
  trees=("$here")
fi
maps=()
for m in "$@"; do maps+=("$(realpath "$m")"); done
if [ ${#maps[@]} -eq 0 ]; then
  mapfile -t maps < <(find "$data/public" "$data/simulated" -name '*.fits' -o -name '*.fits.gz' | sort -V)
fi
out=${OUT:-$here/benchmarks/results/speed/plan_wall_side_by_side.txt}
mkdir -p "$(dirname "$out")"
tmp=$(mktemp -d)
: > "$out"
echo "# $(date -u +%FT%TZ) trees: ${trees[*]}; ${#maps[@]} maps; greedy x$repeat; $(nproc) cores" | tee -a "$out"
run() {  # tree_index map arm
  local tree=${trees[$1]} m=$2 arm=$3 name tag t0 t1 rc opt=()
  name=$(basename "$(dirname "$m")")_$(basename "$m" | sed 's/\.fits.*//')
  tag=$(basename "$tree")
  [ "$arm" = greedy ] && opt=(--solver greedy)
  t0=$(date +%s.%N)
  (cd "$tmp" && PYTHONPATH=$tree $py -m mushrooms.cli plan "$m" "${opt[@]}" --brief -o "$tmp/p.json" > "$tmp/log" 2>&1)
  rc=$?; t1=$(date +%s.%N)
  $py - "$tmp/p.json" "$tag" "$name" "$arm" "$t0" "$t1" "$rc" <<'EOF' | tee -a "$out"
import json, sys
path, tag, name, arm, t0, t1, rc = sys.argv[1:]
wall = float(t1) - float(t0)
try:
    d = json.load(open(path)); m = d.get("metrics", {})
except (OSError, ValueError):
    d, m = {}, {}
print(tag, name, arm, f"{wall:.2f}", f"rc={rc}", m.get("solver", d.get("type", "-")), m.get("coverage", 0.0),
      m.get("upper_bound"), m.get("upper_bound_method"), m.get("runtime_s"), m.get("expected_detections"),
      m.get("coverage_as_executed"), (m.get("budget") or {}).get("spent"),
      (m.get("budget") or {}).get("kind", "-"), (m.get("budget") or {}).get("interrupted", "-"))
EOF
  grep -o 'times: .*' "$tmp/log" | sed 's/^/    /' | tee -a "$out"
  rm -f "$tmp/p.json"
}
i=0
for m in "${maps[@]}"; do
  order=(0); [ ${#trees[@]} -eq 2 ] && { [ $((i % 2)) -eq 0 ] && order=(0 1) || order=(1 0); }
  for k in "${order[@]}"; do
    for _ in $(seq "$repeat"); do run "$k" "$m" greedy; done
    run "$k" "$m" default
  done
  echo "# load $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$out"
  i=$((i + 1))
done
rm -rf "$tmp"
$py "$here/benchmarks/speed/plan_wall_summary.py" --trees "$out" | tee "$out.summary.txt"
