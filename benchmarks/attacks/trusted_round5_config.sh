#!/usr/bin/env bash
# Reproductions of issue 52's findings 5 and 6 and of the config/state/replay/rehearse LOW items.
#
#   benchmarks/attacks/trusted_round5_config.sh [REPO]     (REPO: the checkout to run, default: this one)
#
# Runs `python -m mushrooms.cli` of REPO (PYTHONPATH=REPO) with /work/main/.venv's python (or $PYTHON),
# in a scratch directory; every case prints its command, the last lines of its output and its exit
# status.  Nothing is written outside the scratch directory: the device case is a link to /dev/null
# inside it (a state path of /dev/null itself once made /dev/null-journal and /dev/mushrooms-triggers).
# The rehearsal cases are bounded by `timeout` (they once never ended).  Takes 2-4 minutes.
set -u
REPO=$(cd "${1:-$(dirname "$0")/../..}" && pwd)
PY=${PYTHON:-/work/main/.venv/bin/python}
W=$(mktemp -d /tmp/mushrooms-round5-config-XXXXXX)
MAP=$REPO/tests/data/skymaps/MS220722v_bayestar.multiorder.fits
NOTICE=$REPO/mushrooms/data/demo/MS260605l-preliminary.json
echo "# repo $REPO at $(git -C "$REPO" rev-parse --short HEAD 2>/dev/null || echo "(not a git checkout)")$(git -C "$REPO" diff --quiet 2>/dev/null || echo " +changes"); scratch $W"
echo "# $(uptime)"
cd "$W" || exit 1

run() {  # run TIMEOUT_S ARGS...: one case
    local t=$1; shift
    echo
    echo "\$ mushrooms $*"
    local s=$SECONDS
    PYTHONPATH=$REPO timeout "$t" "$PY" -m mushrooms.cli --log-level WARNING "$@" > out.txt 2>&1
    local rc=$?
    tail -4 out.txt | cut -c1-400
    echo "exit=$rc after $((SECONDS - s)) s$([ $rc = 124 ] && echo ' (killed by timeout: it did not end)')"
}

echo "## 5: a value that is not a table where a table belongs"
printf '[scheduler]\nslew = 1\nsolver = "greedy"\nnside = 64\n' > slew1.toml
run 300 plan "$MAP" -o p1.json --config slew1.toml
for v in 1 2.5 true '"fast"' '[1,2]'; do
    run 300 plan "$MAP" -o p2.json --set "scheduler.slew=$v" --set scheduler.solver=greedy --set scheduler.nside=64
done
printf 'scheduler = 1\n' > section.toml
run 60 plan "$MAP" -o p3.json --config section.toml
run 60 plan "$MAP" -o p4.json --set 'bench.maglim=3'
run 60 plan "$MAP" -o p5.json --config slew1.toml --set scheduler.slew.readout_s=9
echo "garbage" > curve.txt
run 300 plan "$MAP" -o p6.json --set "scheduler.detection_lightcurve=\"$W/curve.txt\"" --set scheduler.solver=greedy --set scheduler.nside=64

echo
echo "## LOW: did you mean; an array of strings"
run 60 plan "$MAP" -o p7.json --set scheduler.slwe=1
run 60 plan "$MAP" -o p8.json --set schedular.solver=greedy
run 60 plan "$MAP" -o p9.json --set 'scheduler.filters=[1,2]'

echo
echo "## 6: rehearse"
printf '[scheduler]\nsolver = "greedy"\nnside = 64\n' > greedy.toml
run 60 rehearse --config greedy.toml --timeout nan --set policy.max_skymap_bytes=2880
run 60 rehearse --config greedy.toml --timeout inf --set policy.max_skymap_bytes=2880
# a first-stage job failure (the notice's map is larger than [policy] allows: decision=rejected)
run 300 rehearse --config greedy.toml --timeout 240 --set policy.max_skymap_bytes=2880
mkdir -p "$W/tmp"
TMPDIR=$W/tmp run 300 rehearse --config greedy.toml
echo "temporary rehearsal directories left after a rehearsal that passed: $(ls "$W/tmp" | grep -c mushrooms-rehearse-)"

echo
echo "## LOW: a FIFO, a directory or a device as the state file"
mkdir st && mkfifo st/fifo.sqlite && mkdir st/dir.sqlite && ln -s /dev/null st/dev.sqlite
for s in st/fifo.sqlite st/dir.sqlite st/dev.sqlite; do
    run 60 status --state "$s"
    run 120 trigger MS260605l --state "$s"
    run 120 replay "$NOTICE" --out r-out --state "$s"
    run 60 run --bootstrap 127.0.0.1:9 --state "$s"
done
echo "created beside them: $(ls st | tr '\n' ' ')"

echo
echo "## LOW: replay of a malformed notice"
printf '{not json' > bad.json
run 300 replay bad.json "$NOTICE" --allow-mock --out r2 --config greedy.toml

echo
echo "# $(uptime)"
rm -rf "$W"
