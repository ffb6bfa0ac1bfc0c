"""Expected kilonova detections of a plan, from the sky map's 3-D posterior.

The probability that a plan detects the kilonova is an integral over the
sky map's position and distance posterior: a pixel ``l`` holding probability
``w_l`` counts for the probability that the source, at its conditional
distance posterior ``p(r | l) ∝ r² N(r; DISTMU_l, DISTSIGMA_l)``, lies within
the *reach* of the deepest exposure covering it::

    E = Σ_l w_l · F_l( max_{e covers l} r_e )                               (X1)
    r_e = 10^((m5_e − M_band(t_e − t_merger)) / 5 − 5)  Mpc                 (X2)

``F_l`` is the conditional distance CDF (:func:`ligo.skymap.distance.conditional_cdf`),
``m5_e`` the exposure's limit (:mod:`.depth`, the difference image's, D2) and ``M_band`` the
source model (:mod:`.kilonova`).  One detection suffices, as in the
evaluation's injection recovery, of which (X1) is the exact expectation (the
Monte Carlo efficiency converges to it).  Maps without distance layers have
no expected detections (None).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from astropy.time import Time, TimeDelta

from .depth import ZTF_DEPTH, DepthModel, limiting_magnitude, sky_conditions
from .kilonova import Kilonova
from ..plan.document import Observation, Plan
from ..sky.footprints import Footprints
from ..sky.skymap import SkyMap

__all__ = ["reach_mpc", "distance_cdf", "exposure_depths", "plan_reach", "expected_detections"]


def reach_mpc(maglim: np.ndarray, absmag: np.ndarray) -> np.ndarray:
    """Largest luminosity distance (Mpc) at which ``absmag`` is at least as bright as ``maglim``, (X2).

    ``0`` where the source is not defined (``absmag`` infinite) or the
    limit is ``-inf``.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        r = 10.0 ** ((np.asarray(maglim, float) - np.asarray(absmag, float)) / 5.0 - 5.0)
    return np.where(np.isfinite(r), r, 0.0)


def distance_cdf(skymap: SkyMap, ipix: np.ndarray, r_mpc: np.ndarray) -> np.ndarray:
    """P(D <= r | pixel) from the distance layers (DISTNORM recomputed).

    Parameters
    ----------
    skymap : SkyMap
        With distance layers.
    ipix : numpy.ndarray
        NESTED pixels at the map's working resolution.
    r_mpc : numpy.ndarray
        Distances (Mpc), same shape as ``ipix``.

    Returns
    -------
    numpy.ndarray
        CDF values in [0, 1]; 0 where a pixel's layers are not finite.
    """
    from ligo.skymap.distance import conditional_cdf, parameters_to_moments

    mu = skymap.distmu[ipix]
    sigma = skymap.distsigma[ipix]
    r = np.asarray(r_mpc, float)
    ok = np.isfinite(mu) & np.isfinite(sigma) & (sigma > 0) & (r > 0)
    out = np.zeros(r.shape)
    with np.errstate(all="ignore"):
        norm = parameters_to_moments(mu[ok], sigma[ok])[2]
        out[ok] = conditional_cdf(r[ok], mu[ok], sigma[ok], norm)
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0)


def exposure_depths(observations: Sequence[Observation], start: Time,
                    depth: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """(m,) 5-sigma limiting magnitude (AB) of each exposure's difference image, (D2).

    Taken at mid-exposure for the field centre's airmass, Moon and twilight
    (:func:`.depth.sky_conditions`); ``start`` is the time the observations'
    ``start`` seconds count from.  The plan document's ``limiting_mag``,
    the reach (X2) and the evaluation's injection recovery all come from here.
    """
    if not observations:
        return np.zeros(0)
    return _depths(observations, *_mid_exposures(observations, start), depth)


def _mid_exposures(observations: Sequence[Observation], start: Time) -> tuple[np.ndarray, np.ndarray, Time]:
    """(exposure times (s), filters, mid-exposure times) of observations timed from ``start``."""
    expo = np.array([o.exposure_s for o in observations], dtype=float)
    mid = np.array([o.start for o in observations], dtype=float) + 0.5 * expo
    filters = np.array([o.filter for o in observations], dtype=str)
    return expo, filters, Time(start) + TimeDelta(mid, format="sec")


def _depths(observations: Sequence[Observation], expo: np.ndarray, filters: np.ndarray, times: Time,
            depth: DepthModel) -> np.ndarray:
    """(D2) limiting magnitudes at the given mid-exposure times."""
    cond = sky_conditions(np.array([o.ra for o in observations]), np.array([o.dec for o in observations]), times,
                          depth.location)
    return limiting_magnitude(filters, expo, cond, depth)


def plan_reach(plan: Plan, kilonova: Kilonova, merger_time: Time,
               depth: DepthModel = ZTF_DEPTH) -> np.ndarray:
    """(m,) reach (Mpc) of each planned exposure for a kilonova, (X2).

    The limit is :func:`exposure_depths` (mid-exposure, the field centre's
    airmass, Moon and twilight); the source's age at mid-exposure since
    ``merger_time``.
    """
    obs = plan.observations
    if not obs:
        return np.zeros(0)
    expo, filters, times = _mid_exposures(obs, plan.start)
    m5 = _depths(obs, expo, filters, times, depth)
    age = (times - Time(merger_time)).to_value("day")
    absmag = np.empty(len(obs))
    for band in np.unique(filters).tolist():  # loop over bands, not exposures
        sel = filters == band
        absmag[sel] = kilonova.absolute_mag(band, age[sel])
    return reach_mpc(m5, absmag)


def expected_detections(plan: Plan, skymap: SkyMap, footprints: Footprints, kilonova: Kilonova,
                        merger_time: Time | None = None, depth: DepthModel = ZTF_DEPTH) -> float | None:
    """Probability that the plan detects the kilonova, equation (X1).

    Parameters
    ----------
    plan : Plan
        The plan (field centres, filters, times).
    skymap : SkyMap
        Position and distance posterior at ``footprints.nside``.
    footprints : Footprints
        Pixel lists of (at least) the planned fields.
    kilonova : Kilonova
        Source model.
    merger_time : astropy.time.Time, optional
        Defaults to the map's event time.
    depth : DepthModel
        Limiting-magnitude model.

    Returns
    -------
    float or None
        Expected detections in [0, 1]; None when the map has no distance
        layers or no merger time is known.
    """
    t0 = merger_time if merger_time is not None else skymap.event_time
    if not skymap.has_distance or t0 is None:
        return None
    if not plan.observations:
        return 0.0
    reach = plan_reach(plan, kilonova, t0, depth)
    fids = np.array([o.field_id for o in plan.observations])
    uniq, inv = np.unique(fids, return_inverse=True)
    best_field = np.zeros(uniq.size)
    np.maximum.at(best_field, inv, reach)
    best_pix = np.zeros(skymap.prob.size)
    for fid, r in zip(uniq.tolist(), best_field.tolist()):  # one vectorised update per field
        pix = footprints.pixels(int(fid))
        best_pix[pix] = np.maximum(best_pix[pix], r)
    pix = np.flatnonzero(best_pix > 0)
    return float(np.sum(skymap.prob[pix] * distance_cdf(skymap, pix, best_pix[pix])))
