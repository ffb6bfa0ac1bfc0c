import sys, glob, os, warnings
import numpy as np
warnings.simplefilter("ignore")
from mushrooms.scheduler_core import read_skymap
out = sys.argv[1]; nside = int(sys.argv[2]); os.makedirs(out, exist_ok=True)
for f in sorted(glob.glob('/tmp/h15b/maps/*')):
    m = read_skymap(f, nside=nside)
    np.savez(os.path.join(out, os.path.basename(f) + '.npz'), prob=m.prob, distmu=m.distmu, distsigma=m.distsigma)
