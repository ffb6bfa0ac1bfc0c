"""Summarise benchmarks/plan_wall_side_by_side.sh output: per-map ratio, medians, coverage / bound.

Usage: python benchmarks/plan_wall_summary.py OUTPUT.txt  (with ARM_CONFIG runs: their medians too)
"""
import sys, statistics as st
rows = {}
for line in open(sys.argv[1]):
    f = line.split()
    if len(f) < 9 or not f[3].startswith("rc="):
        continue
    name, s, wall, rc, solver, cov, bound, method, rt = f[:9]
    rows.setdefault(name, {})[s] = dict(wall=float(wall), rc=rc, solver=solver, cov=float(cov),
                                        bound=None if bound == "None" else float(bound), method=method, rt=float(rt))
both = {n: r for n, r in rows.items() if "greedy" in r and "default" in r}
print(f"maps {len(both)}")
print(f"{'map':34s} {'greedy s':>8s} {'default s':>9s} {'ratio':>6s} {'cov g':>7s} {'cov d':>7s} {'bound':>7s} {'d/bound':>7s} solver")
ratios, walls_d, walls_g, cb, below, dg = [], [], [], [], 0, []
for n, r in both.items():
    g, d = r["greedy"], r["default"]
    ratio = d["wall"] / g["wall"]
    ratios.append(ratio); walls_d.append(d["wall"]); walls_g.append(g["wall"])
    b = d["bound"]
    x = d["cov"] / b if b and b > 0 else float("nan")
    if b and b > 0:
        cb.append(x); below += x < 0.8
    if g["cov"] > 0:
        dg.append(d["cov"] / g["cov"])
    print(f"{n:34s} {g['wall']:8.2f} {d['wall']:9.2f} {ratio:6.2f} {g['cov']:7.4f} {d['cov']:7.4f} {b or 0:7.4f} {x:7.3f} {d['solver']}")
print(f"median wall greedy {st.median(walls_g):.2f} s, default {st.median(walls_d):.2f} s; median ratio {st.median(ratios):.2f}, mean ratio {st.mean(ratios):.2f}")
print(f"coverage/bound (default, {len(cb)} maps with a bound): mean {st.mean(cb):.3f} median {st.median(cb):.3f}; below 0.8: {below}")
print(f"mean coverage default {st.mean(r['default']['cov'] for r in both.values()):.4f} vs greedy {st.mean(r['greedy']['cov'] for r in both.values()):.4f}: x{st.mean(r['default']['cov'] for r in both.values())/st.mean(r['greedy']['cov'] for r in both.values()):.3f}; per-map ratio mean x{st.mean(dg):.3f}")
arm = {n: r for n, r in both.items() if "config" in r}
if arm:  # the ARM_CONFIG runs: wall time and coverage beside the default's
    wc = [r["config"]["wall"] for r in arm.values()]
    print(f"config arm on {len(arm)} maps: median wall {st.median(wc):.2f} s (default {st.median(r['default']['wall'] for r in arm.values()):.2f} s, "
          f"greedy {st.median(r['greedy']['wall'] for r in arm.values()):.2f} s); median ratio to greedy "
          f"{st.median(r['config']['wall'] / r['greedy']['wall'] for r in arm.values()):.2f}; mean coverage "
          f"{st.mean(r['config']['cov'] for r in arm.values()):.4f} (default {st.mean(r['default']['cov'] for r in arm.values()):.4f})")
