"""Summarise benchmarks/speed/plan_wall_side_by_side.sh output.

Usage:
    python benchmarks/speed/plan_wall_summary.py --trees OUTPUT.txt   (rows ``tree map arm wall rc ...``: one or two trees)
    python benchmarks/speed/plan_wall_summary.py OUTPUT.txt           (the older one-tree rows ``map arm wall rc ...``)

``--trees``: per tree, greedy wall (each map's median over its repeats) and default wall, their median and p95
over the maps, the default / greedy ratio, coverage of the default vs greedy and vs the certified bound, expected
detections and coverage as executed; then the maps where the two trees' default plans differ most.
"""
import math
import statistics as st
import sys


def pct(xs, q):
    xs = sorted(xs)
    return xs[min(len(xs) - 1, max(0, int(round(q / 100 * (len(xs) - 1)))))] if xs else float("nan")


def num(x):
    return None if x in ("None", "-") else float(x)


def trees_summary(path):
    rows = {}  # tree -> map -> arm -> list of runs
    order = []
    for line in open(path):
        f = line.split()
        if len(f) < 12 or not f[4].startswith("rc="):
            continue
        tree, name, arm, wall, rc, solver, cov, bound, method, rt, det, exe = f[:12]
        if tree not in order:
            order.append(tree)
        work = num(f[12]) if len(f) > 12 else None  # metrics.budget.spent (work s), rows written since issue 55
        rows.setdefault(tree, {}).setdefault(name, {}).setdefault(arm, []).append(dict(
            wall=float(wall), rc=rc, solver=solver, cov=float(cov), bound=num(bound), det=num(det), exe=num(exe),
            work=work, runtime=num(rt)))
    maps = sorted(set.intersection(*(set(rows[t]) for t in order)))
    maps = [m for m in maps if all("greedy" in rows[t][m] and "default" in rows[t][m] for t in order)]
    print(f"maps {len(maps)}; trees {', '.join(order)}")
    print(f"{'tree':>12s} {'greedy p50':>10s} {'p95':>6s} {'default p50':>11s} {'p95':>6s} {'ratio p50':>9s} "
          f"{'cov d/g':>7s} {'d>=g':>5s} {'cov d/bound':>11s} {'det d':>7s} {'det g':>7s} {'exec d':>7s} {'failed':>6s}")
    per = {}
    for t in order:
        g = [st.median(r["wall"] for r in rows[t][m]["greedy"]) for m in maps]
        d = [rows[t][m]["default"][0]["wall"] for m in maps]
        cg = [rows[t][m]["greedy"][0]["cov"] for m in maps]
        cd = [rows[t][m]["default"][0]["cov"] for m in maps]
        b = [rows[t][m]["default"][0]["bound"] for m in maps]
        dets = [(rows[t][m]["default"][0]["det"], rows[t][m]["greedy"][0]["det"]) for m in maps]
        dets = [x for x in dets if x[0] is not None and x[1] is not None]
        exe = [rows[t][m]["default"][0]["exe"] or 0.0 for m in maps]
        cb = [c / x for c, x in zip(cd, b) if x]
        failed = sum(r["rc"] != "rc=0" for m in maps for arm in rows[t][m].values() for r in arm)
        per[t] = dict(cd=cd)
        print(f"{t:>12s} {st.median(g):10.2f} {pct(g, 95):6.2f} {st.median(d):11.2f} {pct(d, 95):6.2f} "
              f"{st.median(x / y for x, y in zip(d, g)):9.2f} {sum(cd) / max(sum(cg), 1e-12):7.3f} "
              f"{sum(x >= y - 1e-4 for x, y in zip(cd, cg)):2d}/{len(maps):<2d} {st.mean(cb) if cb else math.nan:11.3f} "
              f"{st.mean(x[0] for x in dets) if dets else math.nan:7.4f} "
              f"{st.mean(x[1] for x in dets) if dets else math.nan:7.4f} {st.mean(exe):7.4f} {failed:6d}")
    print("(greedy: each map's median over its repeats; ratio: default / greedy wall per map; cov d/g: sum of the "
          "default's coverage over greedy's; cov d/bound: mean over maps with a bound; det: mean expected "
          "detections over maps with distance layers; exec: mean coverage_as_executed of the default)")
    for t in order:  # the load-free measure: the default plan's work seconds (deterministic budget)
        work = [rows[t][m]["default"][0]["work"] for m in maps if rows[t][m]["default"][0]["work"] is not None]
        rt = [rows[t][m]["default"][0]["runtime"] for m in maps if rows[t][m]["default"][0]["runtime"] is not None]
        both = [(r["runtime"], r["work"]) for m in maps for r in rows[t][m]["default"][:1]
                if r["runtime"] is not None and r["work"]]
        if work and rt and both:
            print(f"{t}: default work seconds (metrics.budget.spent) p50 {st.median(work):.2f} p95 {pct(work, 95):.2f} "
                  f"max {max(work):.2f} over {len(work)} maps; its metrics.runtime_s p50 {st.median(rt):.2f} "
                  f"p95 {pct(rt, 95):.2f}; median runtime / work {st.median(r / w for r, w in both):.2f}")
    if len(order) == 2:
        a, b = order
        diff = sorted(((rows[b][m]["default"][0]["cov"] - rows[a][m]["default"][0]["cov"], m) for m in maps))
        print(f"default coverage {b} - {a}: mean {st.mean(x for x, _ in diff):+.4f}; worst "
              + ", ".join(f"{m} {x:+.4f}" for x, m in diff[:5]) + "; best "
              + ", ".join(f"{m} {x:+.4f}" for x, m in diff[-3:]))
        print(f"{'map':40s} " + " ".join(f"{t + ' ' + k:>16s}" for t in order for k in ("greedy s", "default s", "cov d")))
        for m in maps:
            cells = []
            for t in order:
                cells += [f"{st.median(r['wall'] for r in rows[t][m]['greedy']):16.2f}",
                          f"{rows[t][m]['default'][0]['wall']:16.2f}", f"{rows[t][m]['default'][0]['cov']:16.4f}"]
            print(f"{m:40s} " + " ".join(cells))


def one_tree_summary(path):
    rows = {}
    for line in open(path):
        f = line.split()
        if len(f) < 9 or not f[3].startswith("rc="):
            continue
        name, s, wall, rc, solver, cov, bound, method, rt = f[:9]
        rows.setdefault(name, {})[s] = dict(wall=float(wall), cov=float(cov), bound=num(bound), solver=solver)
    both = {n: r for n, r in rows.items() if "greedy" in r and "default" in r}
    print(f"maps {len(both)}")
    g = [r["greedy"]["wall"] for r in both.values()]
    d = [r["default"]["wall"] for r in both.values()]
    print(f"median wall greedy {st.median(g):.2f} s, default {st.median(d):.2f} s; median ratio "
          f"{st.median(x / y for x, y in zip(d, g)):.2f}")


if __name__ == "__main__":
    if sys.argv[1] == "--trees":
        trees_summary(sys.argv[2])
    else:
        one_tree_summary(sys.argv[1])
