#!/usr/bin/env bash
# The O4 population study (BNS + NSBH, HLV; recipe `o4` of mushrooms/evaluation/study/recipes.py), run in
# stages of growing size so that partial tables exist early; every stage is resumable and reuses the cache
# (chunks, localised maps) and the results of the stages before it.
#
#   nice -n 19 benchmarks/population_o4.sh            # greedy to DETECTIONS events, then greedy,hybrid
#   STAGES="20 50" SOLVERS_LAST=greedy benchmarks/population_o4.sh
#
# Large files (injections, realised chunks, sky maps, results.jsonl) go under $ROOT (default
# /work/population_o4), outside git; benchmarks/results/population_o4/ gets the small provenance and the
# results in the paper's layout (benchmarks/population_o4_results.py).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=${ROOT:-/work/population_o4}
PY=$(realpath -s "${PY:-.venv/bin/python}")
INJECTIONS=${INJECTIONS:-15000}    # bayestar-inject --nsamples (~3 % are detected at network SNR 8)
SEED=${SEED:-2}
WORKERS=${WORKERS:-1}
STAGES=${STAGES:-"10 25 50 100 250"}
SOLVERS_LAST=${SOLVERS_LAST:-greedy,hybrid}
export PATH="$(dirname "$PY"):$PATH"  # (absolute: the tools run in their own directories)
export OMP_NUM_THREADS=1
mkdir -p "$ROOT"
study() {
  "$PY" -m mushrooms.cli study --simulate "$INJECTIONS" --population o4 --seed "$SEED" --chunk 50 \
    --workers "$WORKERS" --out "$ROOT/study" --cache "$ROOT/cache" "$@"
}
for k in $STAGES; do
  echo "== $(date -u +%FT%TZ) stage: $k detections, greedy" >&2
  study --detections "$k" --solvers greedy
done
last=${STAGES##* }
echo "== $(date -u +%FT%TZ) stage: $last detections, $SOLVERS_LAST" >&2
study --detections "$last" --solvers "$SOLVERS_LAST"
echo "== $(date -u +%FT%TZ) done" >&2
