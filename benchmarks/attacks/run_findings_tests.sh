#!/bin/sh
# Run the robustness finding tests (creation order, crashes, ranges, hostile input) against a tree: run_findings_tests.sh TREE LABEL
# TREE's mushrooms package is used (PYTHONPATH=TREE); the tests are h25's (copied into TREE/tests for the pre-fix tree).
TREE=${1:?usage: run_findings_tests.sh TREE LABEL}; LABEL=${2:?usage: run_findings_tests.sh TREE LABEL}
PY=${PY:-$(cd "$(dirname "$0")/../.." && pwd)/.venv/bin/python}
OUT=${OUT:-$PWD/benchmarks/results/attacks/findings_tests}/tests_$LABEL
mkdir -p $OUT
cd $TREE
for f in tests/handlers/test_decisions_order.py tests/attack/test_creation_order_crashes_and_pruning.py tests/daemon/test_jobs_robust.py \
         tests/test_config_ranges.py tests/test_cli_files.py tests/daemon/test_consumer_start.py \
         "tests/daemon/test_trigger.py::test_trigger_hands_work_to_the_running_daemon_and_signals" \
         tests/attack/test_hostile_input.py $EXTRA; do
  n=$(echo "$f" | tr '/:' '__')
  (date -u; uptime; echo "PYTHONPATH=$TREE python -m pytest -q -p no:cacheprovider -rA --tb=line $f") > $OUT/$n.txt
  PYTHONPATH=$TREE timeout 1200 nice -n 5 "$PY" -m pytest -q -p no:cacheprovider -rA --tb=line "$f" >> $OUT/$n.txt 2>&1
  echo "rc=$?" >> $OUT/$n.txt
done
