#!/bin/bash
# service-grg and service on 10 events of the frozen run (its maps and config, read only): main (23450c2) and grgfix
while pgrep -f bench8.sh > /dev/null; do sleep 20; done
for t in main_tree after_tree; do
  echo "== $t $(date -u) $(uptime)"
  (cd /tmp/grg/$t && PYTHONPATH=/tmp/grg/$t nice /work/main/.venv/bin/python -m mushrooms.cli bench /tmp/grg/o4maps --solvers service,service-grg --injections 300 --config /work/population_o4_real/config.toml --set scheduler.threads=1 -o /tmp/grg/bench_o4_$t.csv) > /tmp/grg/bench_o4_$t.log 2>&1
  echo "== $t done $(date -u) $(uptime)"
done
