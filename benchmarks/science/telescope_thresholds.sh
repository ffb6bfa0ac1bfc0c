#!/usr/bin/env bash
# Issue 53 (I5): `mushrooms plan MAP --telescopes NAME` with the default thresholds (no min_gain /
# min_coverage in the configuration), then `mushrooms check`, on one checkout.
#   benchmarks/science/telescope_thresholds.sh TREE OUT_DIR [TELESCOPES] [MAPS...]
# TELESCOPES: comma list (default winter,ls4,decam); MAPS default two shared public maps.
# Writes OUT_DIR/<map>_<telescope>.{json,log,check} and one summary line per run to OUT_DIR/summary.tsv.
set -euo pipefail
tree=$(cd "$1" && pwd); out=$(mkdir -p "$2" && cd "$2" && pwd)
scopes=${3:-winter,ls4,decam}; shift $(( $# > 2 ? 3 : $# ))
py=${PY:-/work/main/.venv/bin/python}
data=/work/shared/data/skymaps/public
maps=("$@"); [ ${#maps[@]} -gt 0 ] || maps=("$data/G483432_bayestar.multiorder.fits" "$data/S191216ap_bayestar.multiorder.fits")
run() { (cd "$tree" && PYTHONPATH="$tree" "$py" -m mushrooms.cli "$@"); }
printf 'map\ttelescope\ttype\tfields\texposures\tcoverage\tupper_bound\tmin_gain\tmin_coverage\tcheck\n' > "$out/summary.tsv"
for m in "${maps[@]}"; do
  n=$(basename "$m"); n=${n%%.*}
  for t in ${scopes//,/ }; do
    run plan "$m" --telescopes "$t" --solver "${SOLVER:-greedy}" -o "$out/${n}_${t}.json" > "$out/${n}_${t}.log" 2>&1 || echo "exit $?" >> "$out/${n}_${t}.log"
    rc=0; run check "$out/${n}_${t}.json" "$m" > "$out/${n}_${t}.check" 2>&1 || rc=$?
    "$py" - "$out/${n}_${t}.json" "$n" "$t" "$rc" >> "$out/summary.tsv" <<'PY'
import json, sys
d = json.load(open(sys.argv[1])); m = d.get("metrics", {}); c = d.get("config", {})
obs = d.get("observations", [])
print("\t".join(map(str, [sys.argv[2], sys.argv[3], d.get("type", "plan"), len({o["field_id"] for o in obs}), len(obs),
                          m.get("coverage"), m.get("upper_bound"), c.get("min_gain"), c.get("min_coverage"),
                          "pass" if sys.argv[4] == "0" else f"exit {sys.argv[4]}"])))
PY
  done
done
echo "done $out"
