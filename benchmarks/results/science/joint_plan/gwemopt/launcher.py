import sys
from astropy.utils import iers
iers.conf.auto_download = False
iers.conf.auto_max_age = None
from gwemopt.run import run
run(sys.argv[1:])
