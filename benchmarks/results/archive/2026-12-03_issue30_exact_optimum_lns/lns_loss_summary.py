import csv, sys, statistics
def load(paths):
    out = {}
    for p in paths:
        try:
            for r in csv.DictReader(open(p)):
                out[(r["map"], int(r["k"]))] = r
        except FileNotFoundError:
            pass
    return out
b = load(["/tmp/lns/split_before_k20.csv", "/tmp/lns/split_before_k30.csv", "/tmp/lns/split_before_k30_5.csv"])
a = load(["/tmp/lns/split_after_k20.csv", "/tmp/lns/split_after_k30.csv"])
rows = []
print(f"{'instance':46s} {'best':>7s} {'proven':>6s} {'hyb_bef':>7s} {'hyb_aft':>7s} {'loss_bef':>8s} {'loss_aft':>8s}")
for key in sorted(set(a) & set(b)):
    rb, ra = b[key], a[key]
    best = max(float(rb["optimum"]), float(ra["optimum"]), float(rb["hybrid"]), float(ra["hybrid"]))
    proven = rb["status"] == "optimal" or ra["status"] == "optimal"
    lb, la = best - float(rb["hybrid"]), best - float(ra["hybrid"])
    rows.append((lb, la))
    print(f"{key[0][-40:]:40s} k={key[1]:2d} {best:7.4f} {str(proven):>6s} {float(rb['hybrid']):7.4f} {float(ra['hybrid']):7.4f} {lb:8.4f} {la:8.4f}")
print(f"instances {len(rows)}: mean loss vs best known {statistics.mean(r[0] for r in rows):.4f} -> {statistics.mean(r[1] for r in rows):.4f}; "
      f"max {max(r[0] for r in rows):.4f} -> {max(r[1] for r in rows):.4f}; zero-loss {sum(r[0] <= 1e-6 for r in rows)} -> {sum(r[1] <= 1e-6 for r in rows)}")
