#!/usr/bin/env bash
cd /tmp/depth_bench
uptime > res/uptime_start.txt; date -u >> res/uptime_start.txt
PYTHONPATH=/tmp/depth_bench/src MUSHROOMS_PROGRESS=0 nice -n 19 /work/main/.venv/bin/mushrooms bench maps --config res/config.toml \
  --solvers hybrid,hybrid@e180,hybrid@menu --arm 'e180:exposure_s=180' --arm 'menu:exposure_menu_s=[30,60,120,180,300,600]' \
  --jobs 2 --plots res -o res/results.csv > res/summary.txt 2> res/stderr.txt
echo "exit $?" >> res/summary.txt
uptime > res/uptime_end.txt; date -u >> res/uptime_end.txt
