"""Are two caches' realised chunks the same coincidences? (snr, time of every single, per coinc)."""
import logging, sys
from pathlib import Path
from ligo.skymap.io import events as gw_events
logging.getLogger("BAYESTAR").setLevel(logging.ERROR)

def content(path):
    src = gw_events.open(str(path))
    out = []
    for cid, ev in sorted(src.items()):
        out.append(tuple(sorted((s.detector, round(float(s.snr), 9), round(float(s.time), 6)) for s in ev.singles)))
    return out

a, b = Path(sys.argv[1]), Path(sys.argv[2])
fa = sorted(a.glob("populations/*/realized-*/events-*.xml.gz"))
fb = sorted(b.glob("populations/*/realized-*/events-*.xml.gz"))
common = sorted(set(p.name for p in fa) & set(p.name for p in fb))
same = 0
for name in common:
    ca = content(next(p for p in fa if p.name == name)); cb = content(next(p for p in fb if p.name == name))
    same += ca == cb
    if ca != cb:
        print("DIFFERENT", name, len(ca), len(cb))
print(f"{len(fa)} and {len(fb)} chunk files, {len(common)} in both, {same} with identical coincidences")
