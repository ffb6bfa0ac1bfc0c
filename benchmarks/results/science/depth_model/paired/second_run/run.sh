#!/usr/bin/env bash
cd /tmp/depth_bench
uptime > res2/uptime_start.txt; date -u >> res2/uptime_start.txt
PYTHONPATH=/tmp/depth_bench/src MUSHROOMS_PROGRESS=0 nice -n 10 /work/main/.venv/bin/mushrooms bench maps --config res2/config.toml \
  --solvers hybrid,hybrid@e180,hybrid@menu --arm 'e180:exposure_s=180' --arm 'menu:exposure_menu_s=[30,60,120,180,300,600]' \
  --jobs 2 --plots res -o res2/results.csv > res2/summary.txt 2> res2/stderr.txt
echo "exit $?" >> res2/summary.txt
uptime > res2/uptime_end.txt; date -u >> res2/uptime_end.txt
