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
# Large files (sky maps, the full results.jsonl) go under $ROOT (default /work/population_o4), outside git;
# benchmarks/science/population_o4_results.py commits the small ones: the population (provenance, injections, every
# realised chunk) in SEED_FROM (the recipe's committed `population/` folder), and beside it in `study/` the run's
# config.toml and its finished result records (results.jsonl.gz, the logs). On a new machine ROOT is seeded from
# them first (benchmarks/science/population_o4_seed.py; SEED_FROM empty: no seeding): only what was never realised
# is simulated, and no (map, row) already planned is planned again, nor is an event whose rows are all done
# localised again; the other sky maps are localised again (bayestar-localize-coincs is deterministic given the
# chunk). A result's key holds the configuration's hash, and the configuration names $ROOT/gwemopt-cache: the
# committed config.toml is seeded verbatim, so under another ROOT the keys still match (gwemopt's cache then stays
# at the path it names, which must be writable); a different config.toml plans everything again.
#
# The frozen release (issue 55 item 6) is planned by one commit: run the study from a checkout of it, e.g.
#   git worktree add --detach /work/population_o4_real/code af0ff7d
#   CODE=/work/population_o4_real/code POPULATION=o4-real ROOT=/work/population_o4_real WORKERS=2 \
#     PY=/path/to/venv/bin/python nice -n 19 benchmarks/science/population_o4.sh
# (CODE: the study runs from there, so every row records that commit; this checkout only seeds ROOT. Export
# MUSHROOMS_GWEMOPT_PYTHON, the interpreter with gwemopt, as /work/population_o4_real/run.sh does: without it the
# gwemopt rows still to plan are recorded as failures, "unavailable", and retried by the next run.)
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
# the committed population folder (its sibling study/ holds the committed result records and configuration)
if [ "$POPULATION" = o4 ]; then _seed=population_o4/previous_2026-12-06_o4_recipe; else _seed=population_o4; fi
if [ "$POPULATION" != o4 ] && [ "$POPULATION" != o4-real ]; then _seed=population_${POPULATION//-/_}; fi
SEED_FROM=${SEED_FROM-benchmarks/results/science/$_seed/population}
CONFIG=${CONFIG:-$ROOT/config.toml}
CODE=${CODE:-}                    # a checkout of the frozen commit to run the study from (default: this one)
export PATH="$(dirname "$PY"):$PATH"  # (absolute: the tools run in their own directories)
export OMP_NUM_THREADS=1
mkdir -p "$ROOT"
if [ -n "$SEED_FROM" ]; then  # the population, the configuration and the finished rows (population_o4_seed.py)
  PYTHONPATH="$(pwd)${PYTHONPATH:+:$PYTHONPATH}" "$PY" benchmarks/science/population_o4_seed.py \
    --population "$POPULATION" --injections "$INJECTIONS" --seed "$SEED" --from "$SEED_FROM" --root "$ROOT" \
    --config "$CONFIG"
fi
if [ -n "$CODE" ]; then cd "$CODE" && export PYTHONPATH="$(pwd)${PYTHONPATH:+:$PYTHONPATH}"; fi
if [ ! -e "$CONFIG" ]; then  # (the code's own config.toml; a seeded one, committed with the results, wins)
  { cat config.toml; printf '\n[bench]\ngwemopt_cache_dir = "%s"\n' "$ROOT/gwemopt-cache"; } > "$CONFIG"
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
