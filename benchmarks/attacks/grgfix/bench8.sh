#!/bin/bash
# service, service-grg, greedy on 8 shared maps: main (23450c2) and grgfix
for t in main_tree after_tree; do
  echo "== $t $(date -u) $(uptime)"
  (cd /tmp/grg/$t && PYTHONPATH=/tmp/grg/$t nice /work/main/.venv/bin/python -m mushrooms.cli bench /tmp/grg/maps8 --solvers service,service-grg,greedy --injections 1000 --set scheduler.threads=1 -o /tmp/grg/bench8_$t.csv) > /tmp/grg/bench8_$t.log 2>&1
  echo "== $t done $(date -u) $(uptime)"
done
