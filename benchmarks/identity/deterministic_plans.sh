#!/usr/bin/env bash
# Two runs of `mushrooms plan` on three maps, quiet and under a load of 4 (four `yes > /dev/null`, killed
# afterwards), with [scheduler] deterministic = true: the sha256 of each plan document without its timing fields
# (created, metrics.runtime_s, metrics.latency_s; docs/design/plan-format.md) must not change with the load.
#
#   benchmarks/identity/deterministic_plans.sh              # the work budget (exit 1 if a document changed)
#   DETERMINISTIC=false benchmarks/identity/deterministic_plans.sh   # the wall budget, for contrast (reports, exit 0)
#
# PYTHON (default python3) must import mushrooms' dependencies; this checkout's mushrooms is used.
set -euo pipefail

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PY=${PYTHON:-python3}
DET=${DETERMINISTIC:-true}
SHARED=""
for d in "$ROOT/../shared/data/skymaps" "$ROOT/../../shared/data/skymaps"; do
    [ -d "$d" ] && SHARED=$(cd "$d" && pwd) && break
done
[ -n "$SHARED" ] || { echo "deterministic_plans.sh: ../shared/data/skymaps not found" >&2; exit 2; }
# label, map, start (- : the map's own event time)
MAPS=(
    "MS181101ab|$ROOT/mushrooms/scheduler_core/data/MS181101ab_bayestar.multiorder.fits|2019-05-01T03:00:00"
    "G476954|$SHARED/public/G476954_bayestar.fits.gz|-"
    "bns_o3_11|$SHARED/simulated/bns_o3/11.fits|-"
)
WORK=$(mktemp -d)
LOADERS=()
stop_load() {
    for pid in "${LOADERS[@]}"; do kill "$pid" 2>/dev/null || true; done
    LOADERS=()
}
trap 'stop_load; rm -rf "$WORK"' EXIT

sha_without_timing() {  # the document's sha256 without its timing fields, and a few of its metrics
    PYTHONPATH="$ROOT" "$PY" - "$1" <<'EOF'
import hashlib, json, sys
from mushrooms.scheduler_core.plan.document import without_timing
doc = json.load(open(sys.argv[1]))
body = json.dumps(without_timing(doc), sort_keys=True, separators=(",", ":")).encode()
m = doc.get("metrics") or {}
print(hashlib.sha256(body).hexdigest(), m.get("solver"), m.get("coverage"), m.get("expected_detections"),
      json.dumps(m.get("budget"), sort_keys=True).replace(" ", ""), m.get("runtime_s"))
EOF
}

echo "# $(date -u +%Y-%m-%dT%H:%M:%SZ) $(nproc) cores; deterministic = $DET; $(cd "$ROOT" && git rev-parse --short HEAD 2>/dev/null || echo '-')"
for phase in quiet load4; do
    if [ "$phase" = load4 ]; then
        for _ in 1 2 3 4; do yes > /dev/null & LOADERS+=($!); done
        sleep 5
    fi
    for entry in "${MAPS[@]}"; do
        IFS='|' read -r label map start <<< "$entry"
        args=("$map" -o "$WORK/$phase-$label.json" --brief --set "scheduler.deterministic=$DET")
        [ "$start" != "-" ] && args+=(--start "$start")
        load=$(cut -d' ' -f1 /proc/loadavg)
        t0=$(date +%s.%N)
        (cd "$WORK" && PYTHONPATH="$ROOT" "$PY" -m mushrooms.cli plan "${args[@]}" > "$WORK/$phase-$label.out" 2>&1) \
            || { echo "$phase $label: mushrooms plan failed"; cat "$WORK/$phase-$label.out"; exit 1; }
        wall=$(echo "$(date +%s.%N) - $t0" | bc)
        read -r sha solver coverage expected budget runtime <<< "$(sha_without_timing "$WORK/$phase-$label.json")"
        printf '%-6s %-11s sha256 %s  wall %6.1f s (load %s)  runtime_s %s  %s coverage %s expected %s budget %s\n' \
            "$phase" "$label" "$sha" "$wall" "$load" "$runtime" "$solver" "$coverage" "$expected" "$budget"
        echo "$sha" > "$WORK/$phase-$label.sha"
    done
    stop_load
done
differ=0
for entry in "${MAPS[@]}"; do
    label=${entry%%|*}
    if cmp -s "$WORK/quiet-$label.sha" "$WORK/load4-$label.sha"; then
        echo "$label: identical without timing fields"
    else
        echo "$label: DIFFERENT"
        differ=1
    fi
done
[ "$DET" = true ] && exit $differ
exit 0
