"""The three depth models of the independent scoring side by side, at ZTF-like pointings.

Median 5-sigma limit (AB) of the planner's difference-image model (D1-D2), of
ztf_sim's formula (with the planner's sky brightness) and of the campaigns'
flat medians, in g and r at 30, 180 and 300 s, over random ZTF grid fields at
random night times of 2019 (Sun below -12 deg, airmass <= 2, Moon >= 20 deg
away; the sampling of ``benchmarks/results/science/depth_model/calibration.md``).

Usage: ``python benchmarks/science/depth_models_compare.py [N] > OUT.md``
"""

from __future__ import annotations

import sys

import numpy as np
from astropy.time import Time

from mushrooms.evaluation.independent_depth import CAMPAIGN_DEPTHS, ztf_sim_limiting_mag
from mushrooms.scheduler_core.sky.fields import load_ztf_fields
from mushrooms.scheduler_core.source.depth import limiting_magnitude, sky_brightness, sky_conditions


def pointings(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray, Time]:
    rng = np.random.default_rng(seed)
    fields = load_ztf_fields()
    rows = rng.integers(0, fields.ids.size, 40 * n)
    t = Time(Time("2019-01-01T00:00:00", scale="utc").jd + rng.uniform(0, 365, 40 * n), format="jd", scale="utc")
    return fields.ra[rows], fields.dec[rows], t


def main(n: int = 500) -> None:
    ra, dec, t = pointings(n)
    cond = sky_conditions(ra, dec, t)
    ok = (cond.sun_alt_deg < -12) & (cond.airmass <= 2.0) & (cond.moon_sep_deg >= 20)
    idx = np.flatnonzero(ok)[:n]
    cond = type(cond)(**{k: np.asarray(getattr(cond, k))[idx] for k in cond.__dataclass_fields__})
    print(f"{idx.size} pointings (2019 nights, Sun < -12 deg, airmass <= 2, Moon >= 20 deg)\n")
    print("| band | exposure s | planner (D2) median | ztf_sim formula median | campaign (O3) | campaign (O4a) |")
    print("|---|---|---|---|---|---|")
    for band in ("g", "r"):
        bands = np.full(idx.size, band)
        mu = sky_brightness(bands, cond)
        for expo in (30.0, 180.0, 300.0):
            e = np.full(idx.size, expo)
            d2 = np.median(limiting_magnitude(bands, e, cond))
            zs = np.median(ztf_sim_limiting_mag(bands, e, cond.airmass, mu))
            print(f"| {band} | {expo:.0f} | {d2:.2f} | {zs:.2f} | {CAMPAIGN_DEPTHS['campaign'][band]:.1f} | "
                  f"{CAMPAIGN_DEPTHS['campaign-o4a'][band]:.1f} |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 500)
