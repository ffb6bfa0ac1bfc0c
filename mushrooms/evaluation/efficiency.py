"""Kilonova detection efficiency of a plan, by injection and recovery.

Injections are drawn from the sky map itself: a NESTED pixel at the working
resolution with probability ``prob``, a uniformly random point inside that
pixel, and a luminosity distance from the pixel's conditional distance
posterior, which in ligo.skymap's ansatz is proportional to
``r**2 * N(r; DISTMU, DISTSIGMA)`` (sampled with
:func:`ligo.skymap.distance.conditional_ppf`).

An injection is *detected* by a plan when at least one exposure covers its
pixel (the field's CCD footprint, :class:`~mushrooms.scheduler_core.sky.footprints.Footprints`) while the
kilonova's apparent magnitude at mid-exposure,
``M_band(t - t_merger) + 5 log10(d / 10 pc)``, is brighter than (or equal
to) the exposure's limiting magnitude.  One detection suffices, as in the
paper and gwemopt's injection recovery; a stricter "both filters" rule
would lower every number.  No extinction, no K-correction.

Source model (shared with the scheduler, :mod:`~mushrooms.scheduler_core.source.kilonova` and :mod:`~mushrooms.scheduler_core.source.depth`):
the kilonova is a :class:`~mushrooms.scheduler_core.source.kilonova.Kilonova` (tabulated light curve
extended to the first hours after the merger by the expanding-fireball bound
K1, so injections are alive from the merger time on), and each exposure's
limit comes from :func:`~mushrooms.scheduler_core.source.detection.exposure_depths`: the difference
image's depth (equation D2) for its filter, exposure time, airmass, Moon and twilight at mid-exposure.

First-release scoring ("v1") stays available for comparison: pass a
:class:`~mushrooms.scheduler_core.source.lightcurves.LightCurve` (table only, undetectable before its first
epoch) and a mapping of flat limiting magnitudes per filter for a 300 s
exposure (:data:`DEFAULT_MAGLIM_300S`: g 21.7, r 21.7, i 21.2, from
gwemopt's 20.4 in 30 s scaled by ``1.25 log10(t / 30 s)``) instead of a
:class:`~mushrooms.scheduler_core.source.depth.DepthModel`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Mapping

import healpy as hp
import numpy as np
from astropy.time import Time

from ..scheduler_core.source.depth import DepthModel, ZTF_DEPTH
from ..scheduler_core.source.detection import exposure_depths
from ..scheduler_core.source.kilonova import Kilonova
from ..scheduler_core.source.lightcurves import LightCurve
from ..scheduler_core.plan.document import Plan
from ..scheduler_core.sky.footprints import Footprints
from ..scheduler_core.sky.skymap import SkyMap

__all__ = [
    "Injections",
    "DEFAULT_MAGLIM_300S",
    "REFERENCE_EXPOSURE_S",
    "draw_injections",
    "injection_seed",
    "flat_limiting_magnitude",
    "exposure_limits",
    "detected",
    "detection_efficiency",
    "paired_difference",
]

#: 5-sigma limiting magnitudes (AB) of a 300 s ZTF exposure, per filter.
DEFAULT_MAGLIM_300S: Mapping[str, float] = {"g": 21.7, "r": 21.7, "i": 21.2}
#: Exposure time (s) the limiting magnitudes refer to.
REFERENCE_EXPOSURE_S = 300.0
#: Sub-pixel refinement (HEALPix orders) used to place an injection inside its pixel.
_SUBPIXEL_ORDERS = 8
_MAX_ORDER = 29


@dataclass(frozen=True, eq=False)
class Injections:
    """Simulated kilonovae drawn from a sky map.

    Attributes
    ----------
    ipix : numpy.ndarray
        (n,) NESTED pixel at ``nside`` holding each injection.
    nside : int
        Resolution of ``ipix`` (the sky map's working resolution).
    ra, dec : numpy.ndarray
        (n,) positions (deg), uniformly random inside the pixel.
    distance_mpc : numpy.ndarray
        (n,) luminosity distances (Mpc).
    distance_source : str
        ``"skymap"`` (distance layers) or ``"fixed"``.
    """

    ipix: np.ndarray
    nside: int
    ra: np.ndarray
    dec: np.ndarray
    distance_mpc: np.ndarray
    distance_source: str

    def __len__(self) -> int:
        return int(self.ipix.size)

    @property
    def distance_modulus(self) -> np.ndarray:
        """(n,) distance modulus ``5 log10(d / 10 pc)`` (mag)."""
        return 5.0 * np.log10(self.distance_mpc * 1e5)


def injection_seed(skymap: SkyMap, salt: str = "") -> int:
    """A reproducible 64-bit seed from the sky map's hash (same map, same injections)."""
    return int.from_bytes(hashlib.sha256((skymap.sha256 + salt).encode()).digest()[:8], "little")


def _positions_in_pixels(ipix: np.ndarray, nside: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Uniform random points inside NESTED pixels (deg), via random sub-pixels."""
    order = int(np.log2(nside))
    k = min(_SUBPIXEL_ORDERS, _MAX_ORDER - order)
    sub = rng.integers(0, 4**k, size=ipix.size, dtype=np.int64)
    fine = (ipix.astype(np.int64) << (2 * k)) + sub
    ra, dec = hp.pix2ang(nside << k, fine, nest=True, lonlat=True)
    return ra, dec


def draw_injections(
    skymap: SkyMap,
    n: int = 10_000,
    rng: np.random.Generator | int | None = None,
    fixed_distance_mpc: float | None = None,
) -> Injections | None:
    """Draw kilonova injections from a sky map's position and distance posterior.

    Parameters
    ----------
    skymap : SkyMap
        Sky map at its working resolution.
    n : int
        Number of injections.
    rng : numpy.random.Generator or int, optional
        Random generator or seed; default: a seed from the map's SHA-256,
        so that every solver of one map sees the same injections.
    fixed_distance_mpc : float, optional
        Distance (Mpc) used when the map has no distance layers (and for
        the rare drawn pixels whose layers are not finite).  Without it,
        a map lacking distance layers gives None.

    Returns
    -------
    Injections or None
        None when the map has no distance layers and no fixed distance.
    """
    if n < 1:
        raise ValueError(f"need at least one injection, got {n}")
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(injection_seed(skymap) if rng is None else rng)
    if not skymap.has_distance and fixed_distance_mpc is None:
        return None
    cdf = np.cumsum(skymap.prob)
    u = rng.random(n) * cdf[-1]
    ipix = np.minimum(np.searchsorted(cdf, u, side="right"), cdf.size - 1).astype(np.int64)
    ra, dec = _positions_in_pixels(ipix, skymap.nside, rng)
    p = rng.random(n)
    if skymap.has_distance:
        from ligo.skymap.distance import conditional_ppf, parameters_to_moments

        mu = skymap.distmu[ipix]
        sigma = skymap.distsigma[ipix]
        ok = np.isfinite(mu) & np.isfinite(sigma) & (sigma > 0)
        dist = np.full(n, np.nan)
        # DISTNORM from the two parameters (a layer read elsewhere may not match them).
        with np.errstate(all="ignore"):
            _, _, norm = parameters_to_moments(mu[ok], sigma[ok])
            dist[ok] = conditional_ppf(p[ok], mu[ok], sigma[ok], norm)
        bad = ~(np.isfinite(dist) & (dist > 0))
        if bad.any():
            if fixed_distance_mpc is not None:
                dist[bad] = fixed_distance_mpc
            elif skymap.distmean is not None and np.isfinite(skymap.distmean):
                dist[bad] = skymap.distmean
            else:
                dist[bad] = np.inf  # never detected
        source = "skymap"
    else:
        dist = np.full(n, float(fixed_distance_mpc))
        source = "fixed"
    return Injections(ipix=ipix, nside=skymap.nside, ra=ra, dec=dec, distance_mpc=dist, distance_source=source)


def flat_limiting_magnitude(
    filters: np.ndarray,
    exposure_s: np.ndarray,
    maglim_by_filter: Mapping[str, float] = DEFAULT_MAGLIM_300S,
    reference_exposure_s: float = REFERENCE_EXPOSURE_S,
) -> np.ndarray:
    """Limiting magnitude of each exposure from flat per-filter limits (first-release scoring; D2 is
    :func:`mushrooms.scheduler_core.source.depth.limiting_magnitude`).

    Parameters
    ----------
    filters : array_like of str
        (m,) filter of each exposure.
    exposure_s : array_like
        (m,) exposure times (s).
    maglim_by_filter : mapping
        Limiting magnitude (AB) per filter at ``reference_exposure_s``;
        ``inf`` means infinitely deep.
    reference_exposure_s : float
        Exposure time (s) of ``maglim_by_filter``.

    Returns
    -------
    numpy.ndarray
        (m,) ``maglim[filter] + 1.25 log10(exposure / reference)`` (mag).
    """
    filters = np.asarray(filters, dtype=str)
    missing = sorted(set(filters.tolist()) - set(maglim_by_filter))
    if missing:
        raise ValueError(f"no limiting magnitude for filter(s) {', '.join(missing)}")
    base = np.array([float(maglim_by_filter[f]) for f in filters.tolist()], dtype=float)
    return base + 1.25 * np.log10(np.asarray(exposure_s, float) / reference_exposure_s)


def exposure_limits(plan: Plan, depth: DepthModel | Mapping[str, float] = ZTF_DEPTH,
                    reference_exposure_s: float = REFERENCE_EXPOSURE_S) -> np.ndarray:
    """(m,) limiting magnitude of each planned exposure (AB mag).

    Parameters
    ----------
    plan : Plan
        Observations (field centre, filter, exposure time, start).
    depth : DepthModel or mapping
        A depth model (sky at mid-exposure, equation D2), or flat limits
        per filter at ``reference_exposure_s`` (first-release scoring).
    reference_exposure_s : float
        Exposure time (s) of flat limits.
    """
    obs = plan.observations
    filters = np.array([o.filter for o in obs], dtype=str)
    expo = np.array([o.exposure_s for o in obs], dtype=float)
    if not isinstance(depth, DepthModel):
        return flat_limiting_magnitude(filters, expo, depth, reference_exposure_s)
    return exposure_depths(obs, plan.start, depth)


def _covered(footprints: Footprints, field_ids: np.ndarray, ipix: np.ndarray) -> np.ndarray:
    """(len(field_ids), n) True where an injection's pixel lies in the field."""
    out = np.zeros((field_ids.size, ipix.size), dtype=bool)
    for k, fid in enumerate(field_ids.tolist()):  # one vectorised test per field
        pix = footprints.pixels(int(fid))  # sorted
        if pix.size == 0:
            continue
        pos = np.minimum(np.searchsorted(pix, ipix), pix.size - 1)
        out[k] = pix[pos] == ipix
    return out


def detected(
    plan: Plan,
    lightcurve: Kilonova | LightCurve,
    footprints: Footprints,
    injections: Injections,
    merger_time: Time,
    depth: DepthModel | Mapping[str, float] = ZTF_DEPTH,
    reference_exposure_s: float = REFERENCE_EXPOSURE_S,
    chunk: int = 256,
) -> np.ndarray:
    """Which injections a plan detects.

    Parameters
    ----------
    plan : Plan
        Observations with times in s since ``plan.start``.
    lightcurve : Kilonova or LightCurve
        Source model; each exposure uses the band named like its filter.
        A bare LightCurve is the first-release model (dark before its
        first tabulated epoch).
    footprints : Footprints
        Pixel lists of (at least) the planned fields at ``injections.nside``.
    injections : Injections
        Simulated sources.
    merger_time : astropy.time.Time
        Time of the merger (t = 0 of the light curve).
    depth : DepthModel or mapping
        Depth model (default :data:`~.depth.ZTF_DEPTH`), or flat limiting
        magnitudes per filter at ``reference_exposure_s`` (first release).
    reference_exposure_s : float
        Exposure time (s) of flat limits.
    chunk : int
        Exposures processed at once (bounds memory to ``chunk * n`` floats).

    Returns
    -------
    numpy.ndarray
        (n,) bool: seen brighter than the limit in at least one exposure.
    """
    n = len(injections)
    obs = plan.observations
    if not obs:
        return np.zeros(n, dtype=bool)
    if footprints.nside != injections.nside:
        raise ValueError(f"footprints nside {footprints.nside} != injections nside {injections.nside}")
    fids = np.array([o.field_id for o in obs], dtype=np.int64)
    filters = np.array([o.filter for o in obs], dtype=str)
    expo = np.array([o.exposure_s for o in obs], dtype=float)
    mid = np.array([o.start for o in obs], dtype=float) + 0.5 * expo
    offset_days = float((Time(plan.start) - Time(merger_time)).to_value("day"))
    t_days = offset_days + mid / 86400.0

    absmag = np.empty(fids.size)
    for band in np.unique(filters).tolist():  # loop over bands, not exposures
        sel = filters == band
        absmag[sel] = lightcurve.absolute_mag(band, t_days[sel])
    maglim = exposure_limits(plan, depth, reference_exposure_s)
    # Largest distance modulus at which each exposure still sees the source.
    with np.errstate(invalid="ignore"):
        dmu_max = np.where(np.isfinite(absmag), maglim - absmag, -math.inf)

    uniq, row = np.unique(fids, return_inverse=True)
    cover = _covered(footprints, uniq, injections.ipix)
    mu = injections.distance_modulus
    best = np.full(n, -math.inf)  # deepest distance modulus reached over covering exposures
    for a in range(0, fids.size, chunk):
        rows = row[a:a + chunk]
        reach = np.where(cover[rows], dmu_max[a:a + chunk, None], -math.inf)
        best = np.maximum(best, reach.max(axis=0))
    return np.isfinite(mu) & (mu <= best)


def detection_efficiency(
    plan: Plan,
    skymap: SkyMap,
    lightcurve: Kilonova | LightCurve,
    depth: DepthModel | Mapping[str, float],
    footprints: Footprints,
    injections: Injections,
    merger_time: Time | None = None,
    reference_exposure_s: float = REFERENCE_EXPOSURE_S,
) -> float:
    """Fraction of injected kilonovae a plan detects.

    Parameters
    ----------
    plan : Plan
        The plan to score.
    skymap : SkyMap
        Sky map the injections were drawn from (gives the merger time).
    lightcurve : Kilonova or LightCurve
        Source model (a bare LightCurve: first-release scoring).
    depth : DepthModel or mapping
        :data:`~.depth.ZTF_DEPTH`, or flat limits per filter at
        ``reference_exposure_s`` such as :data:`DEFAULT_MAGLIM_300S`.
    footprints : Footprints
        Field pixel lists at the map's resolution.
    injections : Injections
        From :func:`draw_injections` on ``skymap``.
    merger_time : astropy.time.Time, optional
        Defaults to ``skymap.event_time``.
    reference_exposure_s : float
        Exposure time (s) of ``maglim_by_filter``.

    Returns
    -------
    float
        Detected / injected, in [0, 1]; Monte Carlo error about
        ``sqrt(e (1 - e) / n)``.
    """
    t0 = merger_time if merger_time is not None else skymap.event_time
    if t0 is None:
        raise ValueError("no merger time: the sky map has no event time and none was given")
    hits = detected(plan, lightcurve, footprints, injections, t0, depth, reference_exposure_s)
    return float(hits.mean())


def paired_difference(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Mean difference of two plans' detections on the SAME injections, and its error.

    Parameters
    ----------
    a, b : numpy.ndarray
        (n,) bool detections of plans A and B (from :func:`detected`).

    Returns
    -------
    (diff, err) : tuple of float
        ``eff_A - eff_B`` and its paired Monte Carlo standard error
        ``std(a_i - b_i) / sqrt(n)``, far smaller than the unpaired
        ``sqrt(e (1 - e) / n)`` when the plans share most detections.
    """
    d = np.asarray(a, float) - np.asarray(b, float)
    if d.size < 2:
        return float(d.mean()) if d.size else 0.0, math.inf
    return float(d.mean()), float(d.std(ddof=1) / math.sqrt(d.size))
