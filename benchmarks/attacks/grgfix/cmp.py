"""Two bench CSVs side by side: per (map, row) the given columns before / after, and their means per row."""
import csv, sys
def load(p):
    out={}
    for r in csv.DictReader(open(p)):
        out[(r['skymap'].split('/')[-1], r['solver'])]=r
    return out
b=load(sys.argv[1]); a=load(sys.argv[2])
cols=sys.argv[3].split(',')
f=lambda x: '' if x in ('',None) else (f"{float(x):.4f}" if x.replace('.','',1).replace('-','',1).replace('e','',1).isdigit() else x)
print("| map | row | " + " | ".join(f"{c} before / after" for c in cols) + " |")
print("|---|---|" + "---|"*len(cols))
sums={}
for k in sorted(b):
    if k not in a: continue
    cells=[]
    for c in cols:
        x,y=b[k].get(c,''),a[k].get(c,'')
        cells.append(f"{f(x)} / {f(y)}")
        try:
            fx, fy = float(x or 0), float(y or 0)
        except ValueError:
            continue
        s = sums.setdefault((k[1], c), [0.0, 0.0, 0])
        s[0] += fx; s[1] += fy; s[2] += 1
    print(f"| {k[0]} | {k[1]} | " + " | ".join(cells) + " |")
print()
for (row,c),(x,y,n) in sorted(sums.items()):
    print(f"mean {row} {c}: {x/n:.4f} -> {y/n:.4f} (n={n})")
