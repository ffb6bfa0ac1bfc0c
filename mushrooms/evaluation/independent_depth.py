"""Limiting magnitudes for the independent scoring: the planner's model, ZTF's scheduler's, or the campaigns'.

``depth_model`` of :func:`exposure_depths`:

``"mushrooms"``
    The planner's own difference-image depth (equations D1-D2,
    :mod:`mushrooms.scheduler_core.source.depth`), for comparison.
``"ztf_sim"``
    The limiting-magnitude formula of ZTF's survey scheduler, ztf_sim
    (``ZwickyTransientFacility/ztf_sim`` at c5ab409, BSD-3-Clause; our own
    implementation of its formula, read from ``ztf_sim/magnitudes.py:24-36``
    ``limiting_mag``, ``:88-106`` ``n_pixels``, ``:109-116``
    ``sky_electrons_per_pixel``, ``:39-74`` ``Rstar20``, ``utils.py:156-160``
    ``seeing_at_pointing``, ``constants.py:82`` ``PIXEL_SCALE``)::

        m5 = 20 - 2.5 log10( sqrt(SNR^2 N_pix R_sky / t) / R20_abs(b, alt) )
        N_pix = round( pi (0.673 FWHM / p)^2 ),   FWHM = 2.0" X^0.6,   p = 1.006"/pixel
        R_sky = R20_0(b) 10^(0.4 (20 - mu_b + 2.5 log10 p^2))    (e-/s/pixel)

    with SNR 5, ``R20_abs(b, alt)`` the electrons per second of a 20th-mag
    source through the atmosphere at the field's altitude inside the
    extraction aperture (ztf_sim's ``data/R20_absorbed_ZTF{g,r}.txt``,
    interpolated linearly in altitude, numbers below) and ``R20_0`` the same
    above the atmosphere without aperture cut (g 123.73, r 77.98 e-/s).
    ztf_sim's own sky brightness ``mu_b`` is a gradient-boosted model trained
    on PTF images (``SkyBrightness.py``, pickled, not reproducible here); the
    sky brightness of the planner's model (Krisciunas & Schaefer moonlight,
    airglow, twilight: :func:`~mushrooms.scheduler_core.source.depth.sky_brightness`)
    stands in for it, the one input shared with the planner.  ztf_sim's
    later renormalisation of g and i onto the r range (``utils.py:376-398``)
    serves its scheduling metric, not the depth, and is not applied.  The
    formula is sky-limited science-image depth: no reference-image term.
``"campaign"``
    A flat limit per exposure, whatever its length or sky: the median depth
    of the ZTF/GROWTH O3 campaign, 20.8 in g and r (Kasliwal et al. 2020, ApJ
    905, 145; 13 triggers; not per band).  ``"campaign-o4a"``: 20.2 in g
    (Ahumada et al. 2024, ZTF in O4a, as quoted by issue 55; the r median was
    not found, 20.2 is used for r too).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from astropy.time import Time

__all__ = ["DEPTH_MODELS", "CAMPAIGN_DEPTHS", "R20_ALTITUDE_DEG", "R20_ABSORBED", "R20_UNABSORBED",
           "ZTF_SIM_PIXEL_SCALE", "ZTF_SIM_ZENITH_SEEING", "ztf_sim_npix", "ztf_sim_limiting_mag",
           "exposure_depths"]

#: The switch of the independent scoring.
DEPTH_MODELS = ("mushrooms", "ztf_sim", "campaign", "campaign-o4a")
#: Flat limits (AB mag) of the campaign models.
CAMPAIGN_DEPTHS: Mapping[str, Mapping[str, float]] = {
    "campaign": {"g": 20.8, "r": 20.8},
    "campaign-o4a": {"g": 20.2, "r": 20.2},
}
#: ztf_sim constants (``constants.py:82``; ``utils.py:367``: 2.0" zenith seeing).
ZTF_SIM_PIXEL_SCALE = 1.006
ZTF_SIM_ZENITH_SEEING = 2.0
#: ztf_sim ``Rstar20`` without atmosphere or aperture cut (e-/s of a 20th-mag source), ``magnitudes.py:53-58``.
R20_UNABSORBED: Mapping[str, float] = {"g": 123.73, "r": 77.98}
#: ztf_sim ``data/R20_absorbed_ZTF{g,r}.txt``: altitude (deg) 10, 12, ..., 90 and e-/s of a 20th-mag source.
R20_ALTITUDE_DEG = np.arange(10.0, 90.1, 2.0)
R20_ABSORBED: Mapping[str, np.ndarray] = {
    "g": np.array([58.527023, 62.612198, 65.706007, 68.124835, 70.064318, 71.651515, 72.972372, 74.087037,
                   75.038825, 75.859706, 76.573778, 77.199541, 77.751428, 78.240860, 78.676989, 79.067231,
                   79.417656, 79.733278, 80.018269, 80.276131, 80.509818, 80.721839, 80.914332, 81.089134,
                   81.247822, 81.391761, 81.522128, 81.639946, 81.746103, 81.841370, 81.926414, 82.001813,
                   82.068065, 82.125597, 82.174771, 82.215891, 82.249206, 82.274917, 82.293175, 82.304087,
                   82.307717]),
    "r": np.array([45.310589, 46.879099, 48.032123, 48.914174, 49.609784, 50.171655, 50.634341, 51.021430,
                   51.349572, 51.630850, 51.874246, 52.086573, 52.273093, 52.437930, 52.584363, 52.715033,
                   52.832084, 52.937280, 53.032082, 53.117707, 53.195182, 53.265372, 53.329014, 53.386739,
                   53.439087, 53.486523, 53.529449, 53.568212, 53.603114, 53.634415, 53.662341, 53.687087,
                   53.708822, 53.727688, 53.743809, 53.757285, 53.768201, 53.776623, 53.782603, 53.786177,
                   53.787366]),
}


def ztf_sim_npix(fwhm_arcsec: np.ndarray, pixel_scale: float = ZTF_SIM_PIXEL_SCALE) -> np.ndarray:
    """Pixels of ztf_sim's SNR-maximising aperture (radius 0.673 FWHM), rounded, at least 1."""
    n = np.round(np.pi * (0.673 * np.asarray(fwhm_arcsec, float) / pixel_scale) ** 2)
    return np.maximum(n, 1.0)


def ztf_sim_limiting_mag(bands: np.ndarray, exposure_s: np.ndarray, airmass: np.ndarray, sky_mag: np.ndarray,
                         zenith_seeing: float = ZTF_SIM_ZENITH_SEEING, snr: float = 5.0) -> np.ndarray:
    """5-sigma sky-limited limiting magnitude (AB) by ztf_sim's formula (module notes).

    Parameters
    ----------
    bands : array_like of str
        ``g`` or ``r`` per exposure.
    exposure_s : array_like
        Exposure times (s).
    airmass : array_like
        Airmass (>= 1; ``inf`` below the horizon gives ``-inf``).
    sky_mag : array_like
        Sky surface brightness (mag / arcsec^2).
    zenith_seeing : float
        Zenith FWHM (arcsec).
    snr : float
        Detection threshold.

    Returns
    -------
    numpy.ndarray
        Limiting magnitudes (mag).
    """
    bands = np.asarray(bands, dtype=str)
    x = np.asarray(airmass, float)
    finite = np.isfinite(x) & (x >= 1.0)
    xs = np.where(finite, x, 1.0)
    alt = np.degrees(np.arcsin(1.0 / xs))
    npix = ztf_sim_npix(zenith_seeing * xs ** 0.6)
    r20_abs = np.empty(bands.shape)
    r20_0 = np.empty(bands.shape)
    for b in np.unique(bands).tolist():
        if b not in R20_ABSORBED:
            raise ValueError(f"ztf_sim depth has no band {b!r} (bands: g, r)")
        sel = bands == b
        r20_abs[sel] = np.interp(np.clip(alt[sel], 10.0, 90.0), R20_ALTITUDE_DEG, R20_ABSORBED[b])
        r20_0[sel] = R20_UNABSORBED[b]
    mu_pix = np.asarray(sky_mag, float) - 2.5 * np.log10(ZTF_SIM_PIXEL_SCALE ** 2)
    r_sky = r20_0 * 10.0 ** (0.4 * (20.0 - mu_pix))
    r_star = np.sqrt(snr ** 2 * npix * r_sky / np.asarray(exposure_s, float))
    return np.where(finite, 20.0 - 2.5 * np.log10(r_star / r20_abs), -np.inf)


def exposure_depths(filters: Sequence[str], exposure_s: np.ndarray, ra_deg: np.ndarray, dec_deg: np.ndarray,
                    mid_times: Time, depth_model: str = "campaign") -> np.ndarray:
    """(m,) limiting magnitude of each exposure under ``depth_model`` (:data:`DEPTH_MODELS`)."""
    from ..scheduler_core.source.depth import limiting_magnitude, sky_brightness, sky_conditions

    if depth_model not in DEPTH_MODELS:
        raise ValueError(f"depth_model must be one of {', '.join(DEPTH_MODELS)}, got {depth_model!r}")
    bands = np.asarray(filters, dtype=str)
    expo = np.asarray(exposure_s, float)
    if bands.size == 0:
        return np.zeros(0)
    if depth_model in CAMPAIGN_DEPTHS:
        table = CAMPAIGN_DEPTHS[depth_model]
        missing = sorted(set(bands.tolist()) - set(table))
        if missing:
            raise ValueError(f"{depth_model} depth has no band {', '.join(missing)}")
        return np.array([table[b] for b in bands.tolist()], float)
    cond = sky_conditions(np.asarray(ra_deg, float), np.asarray(dec_deg, float), mid_times)
    if depth_model == "mushrooms":
        return limiting_magnitude(bands, expo, cond)
    return ztf_sim_limiting_mag(bands, expo, cond.airmass, sky_brightness(bands, cond))
