#!/bin/bash
# Run each test of FILE alone against TREE's package: run_per_test.sh TREE FILE TIMEOUT_S OUT
# (8 GB of address space and TIMEOUT_S each: before the fixes some cases hung on a FIFO or grew to GBs).
TREE=$1; FILE=$2; T=$3; OUT=$4
cd $TREE
(date -u; uptime; echo "per test: ulimit -v 8000000; timeout $T python -m pytest -q -p no:cacheprovider -rA --tb=line $FILE::TEST (PYTHONPATH=$TREE)") > $OUT
ulimit -v 8000000
PYTHONPATH=$TREE /work/main/.venv/bin/python -m pytest -q -p no:cacheprovider --collect-only $FILE 2>/dev/null | grep "::" > /tmp/pt_ids.$$
while IFS= read -r id; do
  PYTHONPATH=$TREE timeout $T nice -n 5 /work/main/.venv/bin/python -m pytest -q -p no:cacheprovider -rA --tb=line "$id" > /tmp/pt_case.$$ 2>&1
  rc=$?
  if [ $rc = 124 ]; then echo "TIMEOUT(${T} s: hung or still working) $id" >> $OUT
  elif [ $rc = 137 ] || [ $rc = 139 ]; then echo "KILLED(rc $rc) $id" >> $OUT
  else grep -E "^(PASSED|FAILED|ERROR|SKIPPED)|^/work.*(Error|assert)" /tmp/pt_case.$$ | cut -c1-300 >> $OUT; fi
done < /tmp/pt_ids.$$
echo "end $(date -u)" >> $OUT
