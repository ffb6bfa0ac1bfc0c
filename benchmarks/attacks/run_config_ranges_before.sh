#!/bin/bash
# tests/test_config_ranges.py against the pre-fix tree, one hostile value per run (each a real `plan`
# in-process: some ran for minutes or took 6.5+ GB before the fix): 90 s and 8 GB of address space each.
TREE=${1:?usage: run_config_ranges_before.sh TREE (a checkout of the tree before the fix)}
PY=${PY:-$(cd "$(dirname "$0")/../.." && pwd)/.venv/bin/python}
OUT=${OUT:-$PWD/benchmarks/results/attacks/config_ranges_before/config_ranges_per_case.txt}
mkdir -p "$(dirname "$OUT")"
cd $TREE
(date -u; uptime; echo "per case: ulimit -v 8000000; timeout 90 python -m pytest -q -p no:cacheprovider -rA --tb=line tests/test_config_ranges.py::CASE") > $OUT
ulimit -v 8000000
PYTHONPATH=$TREE timeout 600 nice -n 5 "$PY" -m pytest -q -p no:cacheprovider -rA --tb=line \
  tests/test_config_ranges.py -k "not outside_its_range" 2>&1 | grep -E "^(PASSED|FAILED|ERROR)|^/work|passed|failed" >> $OUT
PYTHONPATH=$TREE "$PY" -m pytest -q -p no:cacheprovider --collect-only tests/test_config_ranges.py -k outside_its_range 2>/dev/null | grep "::" > /tmp/cr_ids.txt
while IFS= read -r id; do
  PYTHONPATH=$TREE timeout 90 nice -n 5 "$PY" -m pytest -q -p no:cacheprovider -rA --tb=line "$id" > /tmp/cr_case.txt 2>&1
  rc=$?
  if [ $rc = 124 ]; then echo "TIMEOUT(90 s: still running, not refused) $id" >> $OUT; else grep -E "^(PASSED|FAILED|ERROR)|^/work.*Error" /tmp/cr_case.txt | cut -c1-300 >> $OUT; fi
done < /tmp/cr_ids.txt
echo "end $(date -u)" >> $OUT
