"""The weather model of the perturbed execution, from the P48's history as ztf_sim replays it.

ztf_sim (``ZwickyTransientFacility/ztf_sim`` at c5ab409, BSD-3-Clause) decides
whether the telescope can observe from PTF's record on the same telescope:
``data/weather_blocks.db`` counts PTF exposures per 30-min block of each year
2009-2015, and a block with at least 5 is observable
(``TelescopeStateMachine.PTFObservabilityDB.check_historical_observability``,
``utils.block_index``).  This script reads that table from a clone of
ztf_sim (``git show``) and reports, per year, the fraction of dark time
(Sun below -12 deg at Palomar) PTF observed, the nights lost whole and in
part, and the part lost on a partial night: the numbers behind
``mushrooms/evaluation/perturbed_execution.py``.

Usage: ``python benchmarks/science/ptf_weather_history.py ZTF_SIM_GIT_DIR > OUT.txt``
"""

from __future__ import annotations

import sqlite3
import subprocess
import sys
import tempfile

import astropy.units as u
import numpy as np
from astropy.coordinates import AltAz, EarthLocation, get_sun
from astropy.time import Time

BLOCK_MIN = 30.0  # ztf_sim constants.TIME_BLOCK_SIZE
NOBS_MIN = 5  # check_historical_observability's default
P48 = EarthLocation(lat=33.3573 * u.deg, lon=-116.8599 * u.deg, height=1700 * u.m)


def main(repo: str) -> None:
    with tempfile.NamedTemporaryFile(suffix=".db") as tmp:
        tmp.write(subprocess.run(["git", "--git-dir", repo, "show", "HEAD:data/weather_blocks.db"], check=True,
                                 capture_output=True).stdout)
        tmp.flush()
        rows = np.array(sqlite3.connect(tmp.name).execute("select year, block, nexps from weather_blocks").fetchall())
    print("year  dark-time observed  nights lost whole  nights lost in part  loss on a partial night")
    for year in range(2009, 2016):
        n = int(366 * 24 * 60 / BLOCK_MIN)
        mids = Time(f"{year}-01-01T00:00:00", scale="utc") + (np.arange(n) + 0.5) * BLOCK_MIN * u.min
        dark = get_sun(mids).transform_to(AltAz(obstime=mids, location=P48)).alt.deg < -12
        r = rows[rows[:, 0] == year]
        seen = np.zeros(n, bool)
        seen[r[:, 1][(r[:, 2] >= NOBS_MIN) & (r[:, 1] < n)]] = True
        night = np.floor(mids.mjd[dark] + 0.3).astype(int)  # local nights (UTC-8 evening to morning)
        s = seen[dark]
        frac = np.array([s[night == k].mean() for k in np.unique(night)])
        part = (frac > 0) & (frac < 1)
        print(f"{year}  {s.mean():.3f}  {(frac == 0).mean():.3f}  {part.mean():.3f}  {1 - frac[part].mean():.3f}")


if __name__ == "__main__":
    main(sys.argv[1])
