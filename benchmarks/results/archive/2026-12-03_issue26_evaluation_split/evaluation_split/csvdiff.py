import csv, sys, re, json
TIME = {"runtime_s", "prepare_s", "solve_s"}
def load(p):
    with open(p) as fh:
        r = list(csv.DictReader(fh))
    return list(r[0].keys()) if r else [], r
def norm(row):
    d = {k: v for k, v in row.items() if k not in TIME}
    d["detection_stage"] = re.sub(r"took [0-9.]+ s", "took T s", d.get("detection_stage", ""))
    return d
for a, b in zip(sys.argv[1::2], sys.argv[2::2]):
    ha, ra = load(a); hb, rb = load(b)
    assert ha == hb, ("header", ha, hb)
    assert len(ra) == len(rb), (len(ra), len(rb))
    nd = sum(norm(x) != norm(y) for x, y in zip(ra, rb))
    for x, y in zip(ra, rb):
        if norm(x) != norm(y):
            print({k: (norm(x)[k], norm(y)[k]) for k in norm(x) if norm(x)[k] != norm(y)[k]})
    print(f"{a} vs {b}: {len(ha)} columns identical, {len(ra)} rows, {nd} differ outside {sorted(TIME)}")
