"""Paired comparison of two bench CSVs (same maps, greedy): efficiency per light curve before/after."""
import sys
import numpy as np
import pandas as pd

before, after = (pd.read_csv(p) for p in sys.argv[1:3])
key = lambda df: df.assign(map=df.skymap.str.split("/").str[-1]).set_index(["map", "solver"])
b, a = key(before), key(after)
common = b.index.intersection(a.index)
b, a = b.loc[common], a.loc[common]
print(f"maps: {len(common)} (greedy), injections/map: {int(a.n_injections.iloc[0])}")
cols = [("coverage", "coverage")] + [(c, c.replace("efficiency_", "eff ")) for c in
        ("efficiency_optimistic", "efficiency_conservative", "efficiency_nsbh")]
print(f"{'quantity':22s} {'before':>8s} {'after':>8s} {'paired change':>22s} {'maps up/down/same':>18s}")
for c, label in cols:
    d = (a[c] - b[c]).to_numpy(float)
    se = d.std(ddof=1) / np.sqrt(d.size)
    up, down = int((d > 1e-12).sum()), int((d < -1e-12).sum())
    print(f"{label:22s} {b[c].mean():8.4f} {a[c].mean():8.4f} {d.mean():+10.5f} ± {se:.5f}   {up:5d}/{down:d}/{d.size - up - down:d}")
same_plan = (a.n_exposures == b.n_exposures) & (np.abs(a.coverage - b.coverage) < 1e-9)
print(f"plans with the same exposures count and coverage (to 1e-9): {int(same_plan.sum())}/{len(common)}")
d = pd.DataFrame({c.replace("efficiency_", ""): a[c] - b[c] for c, _ in cols[1:]})
d["coverage"] = a.coverage - b.coverage
d["area90"] = a.area90_deg2
d["distmean"] = a.distmean_mpc
d["size"] = d[["optimistic", "conservative", "nsbh"]].abs().max(axis=1)
print("\nmaps that moved most (after - before):")
print(d.sort_values("size", ascending=False).drop(columns="size").head(10).round(4).to_string())
