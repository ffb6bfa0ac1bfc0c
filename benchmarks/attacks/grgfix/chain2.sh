#!/bin/bash
while pgrep -f "all_grg_greedy.py greedy /work/population" > /dev/null; do sleep 10; done
cd /tmp
uptime
PYTHONPATH=/work/wt/grgfix nice /work/main/.venv/bin/python /tmp/grg/all_grg_greedy.py greedy $(ls /work/shared/data/skymaps/public/*.fits* /work/shared/data/skymaps/simulated/*/*.fits /work/shared/data/skymaps/simulated/*/*/*.fits 2>/dev/null) 2>&1 | grep -v "INFO\|HiGHS\|Includes"
uptime
PYTHONPATH=/work/wt/grgfix nice /work/main/.venv/bin/python /tmp/grg/all_grg_greedy.py hybrid $(readlink -f /tmp/grg/o4maps/* /tmp/grg/maps8/*) 2>&1 | grep -v "INFO\|HiGHS\|Includes"
uptime
