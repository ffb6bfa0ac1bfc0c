#!/usr/bin/env bash
# The O4 population study (BNS + NSBH, HLV; recipe `o4` of mushrooms/evaluation/study/recipes.py), run in
# stages of growing size so that partial tables exist early; every stage is resumable and reuses the cache
# (chunks, localised maps) and the results of the stages before it.
#
#   nice -n 19 benchmarks/science/population_o4.sh     # per stage K: greedy on the first K events, then all rows
#   STAGES="20 50" SOLVERS_FULL=greedy,hybrid benchmarks/science/population_o4.sh
#   POPULATION=o4-real ROOT=/work/population_o4_real benchmarks/science/population_o4.sh   # O4 as it was (issue 55)
#
# The configuration is the worktree's config.toml with [bench] gwemopt_cache_dir under $ROOT (written once to
# $ROOT/config.toml: gwemopt runs once per event for both of its rows). Keep that file: it is part of every
# result's key, so a rerun with another configuration plans everything again.
#
# Large files (sky maps, results.jsonl) go under $ROOT (default /work/population_o4), outside git;
# benchmarks/results/science/population_o4/ gets the small provenance, the injections and every realised chunk, and
# the results in the paper's layout (benchmarks/science/population_o4_results.py). On a new machine the cache is
# seeded from those committed files first (SEED_FROM, empty: no seeding), so only what was never realised is
# simulated; the sky maps are localised again (bayestar-localize-coincs is deterministic given the chunk).
set -euo pipefail
cd "$(dirname "$0")/../.."
POPULATION=${POPULATION:-o4}      # a recipe of mushrooms/evaluation/study/recipes.py: o4 or o4-real
ROOT=${ROOT:-/work/population_o4}
PY=$(realpath -s "${PY:-.venv/bin/python}")
INJECTIONS=${INJECTIONS:-15000}    # bayestar-inject --nsamples (~4 % are detected at network SNR 8: ~600 events)
SEED=${SEED:-2}
WORKERS=${WORKERS:-1}
STAGES=${STAGES:-"10 25 50 100 250 600"}
SOLVERS_FULL=${SOLVERS_FULL:-service,service-grg,greedy,gwemopt-o4,gwemopt-skyportal,gwemopt-repaired}
GREEDY_FIRST=${GREEDY_FIRST:-0}   # 1: per stage, greedy's rows for every event before the other rows
if [ "$POPULATION" = o4 ]; then _seed=population_o4; else _seed=population_${POPULATION//-/_}; fi
SEED_FROM=${SEED_FROM-benchmarks/results/science/$_seed/population}
CONFIG=${CONFIG:-$ROOT/config.toml}
export PATH="$(dirname "$PY"):$PATH"  # (absolute: the tools run in their own directories)
export OMP_NUM_THREADS=1
mkdir -p "$ROOT"
if [ ! -e "$CONFIG" ]; then
  { cat config.toml; printf '\n[bench]\ngwemopt_cache_dir = "%s"\n' "$ROOT/gwemopt-cache"; } > "$CONFIG"
fi
if [ -n "$SEED_FROM" ] && [ -d "$SEED_FROM/chunks" ]; then
  KEY=$("$PY" -c "from mushrooms.evaluation.study.recipes import recipe_population as r; \
print(r('$POPULATION', $INJECTIONS, seed=$SEED)[0].key())")
  POP="$ROOT/cache/populations/$KEY"
  if [ "$(cat "$SEED_FROM/population.key" 2>/dev/null)" = "$KEY" ]; then
    mkdir -p "$POP/realized-50"
    for f in population.json psds.xml intrinsic_samples.ecsv; do [ -e "$POP/$f" ] || cp "$SEED_FROM/$f" "$POP/"; done
    if [ ! -e "$POP/injections.xml" ] && [ -e "$SEED_FROM/injections.xml.gz" ]; then
      gzip -dc "$SEED_FROM/injections.xml.gz" > "$POP/injections.partial.xml" && mv "$POP/injections.partial.xml" "$POP/injections.xml"
    fi
    cp -n "$SEED_FROM"/chunks/events-*.xml.gz "$POP/realized-50/"
    echo "== seeded $POP from $SEED_FROM" >&2
  else
    echo "== not seeding: $SEED_FROM is not population $KEY" >&2
  fi
fi
study() {
  "$PY" -m mushrooms.cli study --simulate "$INJECTIONS" --population "$POPULATION" --seed "$SEED" --chunk 50 \
    --workers "$WORKERS" --out "$ROOT/study" --cache "$ROOT/cache" --config "$CONFIG" "$@"
}
for k in $STAGES; do
  if [ "$GREEDY_FIRST" = 1 ]; then
    echo "== $(date -u +%FT%TZ) stage: $k detections, greedy" >&2
    study --detections "$k" --solvers greedy
  fi
  echo "== $(date -u +%FT%TZ) stage: $k detections, $SOLVERS_FULL" >&2
  study --detections "$k" --solvers "$SOLVERS_FULL"
done
echo "== $(date -u +%FT%TZ) done" >&2
