#!/usr/bin/env bash
# The O4 population study (BNS + NSBH, HLV; recipe `o4` of mushrooms/evaluation/study/recipes.py), run in
# stages of growing size so that partial tables exist early; every stage is resumable and reuses the cache
# (chunks, localised maps) and the results of the stages before it.
#
#   nice -n 19 benchmarks/population_o4.sh     # per stage K: greedy on the first K events, then all rows
#   STAGES="20 50" SOLVERS_FULL=greedy,hybrid benchmarks/population_o4.sh
#
# The configuration is the worktree's config.toml with [bench] gwemopt_cache_dir under $ROOT (written once to
# $ROOT/config.toml: gwemopt runs once per event for both of its rows). Keep that file: it is part of every
# result's key, so a rerun with another configuration plans everything again.
#
# Large files (injections, realised chunks, sky maps, results.jsonl) go under $ROOT (default
# /work/population_o4), outside git; benchmarks/results/population_o4/ gets the small provenance and the
# results in the paper's layout (benchmarks/population_o4_results.py).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=${ROOT:-/work/population_o4}
PY=$(realpath -s "${PY:-.venv/bin/python}")
INJECTIONS=${INJECTIONS:-15000}    # bayestar-inject --nsamples (~4 % are detected at network SNR 8: ~600 events)
SEED=${SEED:-2}
WORKERS=${WORKERS:-1}
STAGES=${STAGES:-"10 25 50 100 250"}
SOLVERS_FULL=${SOLVERS_FULL:-greedy,hybrid,gwemopt,gwemopt-repaired}
CONFIG=${CONFIG:-$ROOT/config.toml}
export PATH="$(dirname "$PY"):$PATH"  # (absolute: the tools run in their own directories)
export OMP_NUM_THREADS=1
mkdir -p "$ROOT"
if [ ! -e "$CONFIG" ]; then
  { cat config.toml; printf '\n[bench]\ngwemopt_cache_dir = "%s"\n' "$ROOT/gwemopt-cache"; } > "$CONFIG"
fi
study() {
  "$PY" -m mushrooms.cli study --simulate "$INJECTIONS" --population o4 --seed "$SEED" --chunk 50 \
    --workers "$WORKERS" --out "$ROOT/study" --cache "$ROOT/cache" --config "$CONFIG" "$@"
}
for k in $STAGES; do
  echo "== $(date -u +%FT%TZ) stage: $k detections, greedy" >&2
  study --detections "$k" --solvers greedy
  echo "== $(date -u +%FT%TZ) stage: $k detections, $SOLVERS_FULL" >&2
  study --detections "$k" --solvers "$SOLVERS_FULL"
done
echo "== $(date -u +%FT%TZ) done" >&2
