import glob, os, sys
import numpy as np
from ligo.skymap.distance import parameters_to_moments as p2m
for nside in (64, 256):
    rows = []
    for f in sorted(glob.glob(f'/tmp/h15b/L/before{nside}/*.npz')):
        b = np.load(f); a = np.load(f.replace('before', 'after'))
        p = b['prob']; ok = np.isfinite(b['distmu']) & np.isfinite(a['distmu']) & (p > 0)
        mb, sb, _ = p2m(b['distmu'][ok], b['distsigma'][ok]); ma, sa, _ = p2m(a['distmu'][ok], a['distsigma'][ok])
        w = p[ok] / p[ok].sum()
        rows.append((os.path.basename(f)[:-4], np.sum(w * sa) / np.sum(w * sb) - 1, np.sum(w * (ma / mb - 1)),
                     np.sum(w * np.abs(sa / sb - 1)), np.max(np.abs(sa / sb - 1)),
                     p[np.isfinite(b['distmu'])].sum(), p[np.isfinite(a['distmu'])].sum()))
    r = np.array([x[1:] for x in rows])
    print(f"nside {nside}: over {len(rows)} maps, probability-weighted per pixel (after = moments, before = averaged parameters):")
    print(f"  conditional std after/before - 1: mean {r[:,0].mean():+.2e}, max {r[:,0].max():+.2e};  mean distance after/before - 1: mean {r[:,1].mean():+.2e}, max |.| {np.abs(r[:,1]).max():.2e}")
    print(f"  mean |Δstd|/std per map: median {np.median(r[:,2]):.2e}, max {r[:,2].max():.2e}; largest single-pixel |Δstd|/std {r[:,3].max():.2e}")
    print(f"  probability in pixels with finite layers: before {r[:,4].mean():.5f}, after {r[:,5].mean():.5f} (mean over maps)")
    top = sorted(rows, key=lambda x: -abs(x[1]))[:4]
    print("  largest std increase: " + "; ".join(f"{n} {d:+.2%}" for n, d, *_ in top))
