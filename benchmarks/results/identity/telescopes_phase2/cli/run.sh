set -u
cd /work/wt/tel2/benchmarks/results/identity/telescopes_phase2/cli
run() { PYTHONPATH=/work/wt/tel2 /work/main/.venv/bin/python -m mushrooms.cli "$@"; }
P=/work/shared/data/skymaps/public
printf '[scheduler]\nmin_gain = 0.0001\nmin_coverage = 0.001\n' > small_fields.toml
echo "load: $(uptime)"
for m in G483432_bayestar obs-scenarios_sim6_HKL; do
  echo "== mushrooms plan $m --telescopes ztf,ls4 (default solver)"
  run plan $P/$m.multiorder.fits --telescopes ztf,ls4 -o $m.json --targets $m.targets.json --brief 2>&1 | grep -v " INFO "
  echo "exit $?"
  for d in $m.json $m.ls4.json; do echo "== mushrooms check $d"; run check $d $P/$m.multiorder.fits 2>&1 | grep -v " INFO "; done
done
m=obs-scenarios_sim6_HKL
echo "== mushrooms plan $m --telescopes decam (default solver)"
run plan $P/$m.multiorder.fits --telescopes decam -o $m.decam.json --brief 2>&1 | grep -v " INFO "
run check $m.decam.json $P/$m.multiorder.fits 2>&1 | grep -v " INFO "
m=G483432_bayestar
echo "== mushrooms plan $m --telescopes winter (greedy; min_gain 1e-4, min_coverage 1e-3: small_fields.toml)"
run plan $P/$m.multiorder.fits --telescopes winter --solver greedy --config small_fields.toml -o $m.winter.json --brief 2>&1 | grep -v " INFO "
run check $m.winter.json $P/$m.multiorder.fits 2>&1 | grep -v " INFO "
echo "== refused: --queue for ls4"
run plan $P/$m.multiorder.fits --telescopes ztf,ls4 -o x.json --queue q.json 2>&1 | grep -v " INFO "
echo "load: $(uptime)"
rm -f *.html
