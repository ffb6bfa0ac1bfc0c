#!/usr/bin/env bash
# Reproduce the issue-6 benchmark table: every scheduler on every shared sky map.
#
#   benchmarks/quality/run_all.sh                      # greedy,slots,blocks,hybrid,gwemopt(-repaired) on ../shared/data/skymaps
#   SOLVERS=greedy,gwemopt JOBS=2 benchmarks/quality/run_all.sh
#
# gwemopt runs in its own virtual environment (never in .venv); point
# MUSHROOMS_GWEMOPT_PYTHON at its interpreter, see benchmarks/README.md.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PY=${PYTHON:-$ROOT/.venv/bin/python}
MAPS=${MAPS:-$ROOT/../shared/data/skymaps}
SOLVERS=${SOLVERS:-greedy,slots,blocks,hybrid,gwemopt,gwemopt-repaired}
JOBS=${JOBS:-2}
INJECTIONS=${INJECTIONS:-10000}
OUT=${OUT:-$ROOT/benchmarks/results/quality/shared_maps}

if [[ ",$SOLVERS," == *",gwemopt,"* && -z "${MUSHROOMS_GWEMOPT_PYTHON:-}" ]]; then
    if [[ -x /work/gwemopt-venv/bin/python ]]; then
        export MUSHROOMS_GWEMOPT_PYTHON=/work/gwemopt-venv/bin/python
    else
        echo "run_all.sh: gwemopt not set up (MUSHROOMS_GWEMOPT_PYTHON unset); its rows will say 'unavailable'" >&2
    fi
fi
mkdir -p "$OUT"
"$PY" -m mushrooms.cli bench "$MAPS" --solvers "$SOLVERS" --jobs "$JOBS" --injections "$INJECTIONS" \
    -o "$OUT/results.csv" --plots "$OUT" | tee "$OUT/summary.txt"
