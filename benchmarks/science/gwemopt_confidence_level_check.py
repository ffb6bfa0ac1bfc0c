"""Does gwemopt 0.4.2's ``--confidence_level`` change a MOC schedule? Run with gwemopt's interpreter.

Reads one sky map twice through gwemopt's own reader (``gwemopt.io.read_skymap``), with ``--confidence_level`` 1.0
and 0.9, and prints how many pixels each cut keeps in ``skymap_raster_schedule`` and the probability of every
primary-grid ZTF tile computed from ``skymap_schedule`` (what ``gwemopt.tiles.powerlaw_tiles_struct`` uses): when
the two agree, the level does not reach the tiles (gwemopt ``io/skymap.py:317-324``).

    /work/gwemopt-venv/bin/python benchmarks/science/gwemopt_confidence_level_check.py MAP.fits
"""
import sys, numpy as np
from astropy.utils import iers
iers.conf.auto_download = False
from gwemopt.args import parse_args
from gwemopt.params import params_struct
from gwemopt.io import get_skymap, read_skymap
from mocpy import MOC
import gwemopt.moc
out = {}
for cl in ("1.0", "0.9"):
    args = parse_args(["--telescopes", "ZTF", "-e", sys.argv[1], "--confidence_level", cl, "--nside", "256", "--gpstime", "1225000000"])
    params = params_struct(args)
    params["skymap"] = get_skymap(event_name=args.event)
    params, ms = read_skymap(params)
    out[cl] = ms
    print(cl, "schedule rows", len(ms["skymap_schedule"]), "raster_schedule prob>0:", int((ms["skymap_raster_schedule"]["PROB"] > 0).sum()))
# tile probabilities of a few ZTF fields from each skymap_schedule
params["doChipGaps"] = False; params["doUsePrimary"] = True
mocs = gwemopt.moc.create_moc(params)["ZTF"]
keys = list(mocs)[:880]
ps = {cl: np.array(MOC.probabilities_in_multiordermap([mocs[k]["moc"] for k in keys], out[cl]["skymap_schedule"])) for cl in out}
print("tiles with prob>1e-4:", {cl: int((p > 1e-4).sum()) for cl, p in ps.items()}, "max |diff|", float(np.abs(ps["1.0"] - ps["0.9"]).max()), "sum", {cl: float(p.sum()) for cl, p in ps.items()})
