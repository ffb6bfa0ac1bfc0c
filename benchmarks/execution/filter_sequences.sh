#!/usr/bin/env bash
# A g-r-g plan at 180 s of a shared map through the command line, the checker, the queue export and the
# executor model; then a re-plan of its first block's fields done in g and r only (docs/design/sequences.md).
#   benchmarks/execution/filter_sequences.sh [MAP] [OUT_DIR]
# Defaults: bns_o3/2.fits, benchmarks/results/execution/filter_sequences. The venv is /work/main/.venv unless $PY.
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
map=${1:-/work/shared/data/skymaps/simulated/bns_o3/2.fits}
out=$(mkdir -p "${2:-$here/benchmarks/results/execution/filter_sequences}" && cd "${2:-$here/benchmarks/results/execution/filter_sequences}" && pwd)
py=${PY:-/work/main/.venv/bin/python}
run() { (cd "$here" && PYTHONPATH="$here" "$py" -m mushrooms.cli "$@"); }
printf '[scheduler]\nfilters = ["g", "r", "g"]\nexposure_s = 180.0\n' > "$out/grg.toml"
echo "== load: $(uptime)" > "$out/run.txt"
run plan "$map" --config "$out/grg.toml" -o "$out/plan_grg.json" --queue "$out/queue_grg.json" --brief \
    >> "$out/run.txt" 2> "$out/plan_grg.log"
run check "$out/plan_grg.json" "$map" >> "$out/run.txt" 2>> "$out/plan_grg.log"
(cd "$here" && PYTHONPATH="$here" "$py" benchmarks/execution/filter_sequences.py plan "$out/plan_grg.json" "$map" \
    "$out/queue_grg.json" "$out/executed_gr.jsonl") >> "$out/run.txt"
start=$(cd "$here" && PYTHONPATH="$here" "$py" -c "
import json, sys
from astropy.time import Time, TimeDelta
rows = [json.loads(l) for l in open(sys.argv[1])]
print(max((Time(r['start']) + TimeDelta(r['exposure_s'], format='sec')) for r in rows).isot + 'Z')" "$out/executed_gr.jsonl")
run plan "$map" --config "$out/grg.toml" --executed "$out/executed_gr.jsonl" --start "$start" \
    -o "$out/replan_grg.json" --queue "$out/requeue_grg.json" --brief >> "$out/run.txt" 2> "$out/replan_grg.log"
run check "$out/replan_grg.json" "$map" --executed "$out/executed_gr.jsonl" >> "$out/run.txt" 2>> "$out/replan_grg.log"
(cd "$here" && PYTHONPATH="$here" "$py" benchmarks/execution/filter_sequences.py replan "$out/replan_grg.json" "$map" \
    "$out/requeue_grg.json" "$out/executed_gr.jsonl") >> "$out/run.txt"
echo "== load: $(uptime)" >> "$out/run.txt"
cat "$out/run.txt"
