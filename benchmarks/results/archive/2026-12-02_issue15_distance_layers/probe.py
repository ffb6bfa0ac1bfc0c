"""Record what read_skymap gives (prob + distance layers at nside 256) and greedy plans, for before/after."""
import hashlib, json, subprocess, sys, os
from pathlib import Path
import numpy as np
import mushrooms
from mushrooms.scheduler_core import read_skymap

tag, out = sys.argv[1], Path(sys.argv[2])
out.mkdir(parents=True, exist_ok=True)
W = Path("/work/wt/i15b")
MAPS = {
    "MS181101ab_demo": W / "mushrooms/scheduler_core/data/MS181101ab_bayestar.multiorder.fits",
    "MS220722v": W / "tests/data/skymaps/MS220722v_bayestar.multiorder.fits",
    "S200129m_RING": W / "tests/data/skymaps/S200129m_cWB_RING.fits.gz",
    "G476954_flat512": Path("/work/shared/data/skymaps/public/G476954_bayestar.fits.gz"),
    "M403699_moc9": Path("/work/shared/data/skymaps/public/M403699_bayestar.multiorder.fits"),
    "GW170104_flat256": Path("/work/shared/data/skymaps/public/GW170104_G268556_LALInference.fits"),
    "sim6_moc11": Path("/work/shared/data/skymaps/public/obs-scenarios_sim6_HKL.multiorder.fits"),
}
if len(sys.argv) > 3:
    MAPS = {k: v for k, v in MAPS.items() if k in sys.argv[3].split(",")}
print(tag, mushrooms.__file__, file=sys.stderr)
for name, path in MAPS.items():
    m = read_skymap(path, nside=256)
    arrays = {"prob": m.prob}
    if m.has_distance:
        arrays.update(distmu=m.distmu, distsigma=m.distsigma, distnorm=m.distnorm)
    np.savez(out / f"{name}.npz", **arrays)
    plan = out / f"{name}.plan.json"
    subprocess.run([sys.executable, "-m", "mushrooms.cli", "plan", str(path), "--solver", "greedy", "-o", str(plan)],
                   check=True, capture_output=True, text=True)
    doc = json.loads(plan.read_text())
    obs = [(o["field_id"], o["filter"], o.get("start") or o.get("dateobs") or o.get("time")) for o in doc.get("observations", [])]
    digest = hashlib.sha256(json.dumps(obs).encode()).hexdigest()[:16]
    pdig = hashlib.sha256(json.dumps([o.get("probability") for o in doc.get("observations", [])]).encode()).hexdigest()[:16]
    cov = doc.get("metrics", {}).get("coverage")
    print(f"{name:18s} plan_id={doc['plan_id']} observations={len(obs)} obs_sha={digest} obs_prob_sha={pdig} coverage={cov}")
