"""The most expected detections any plan of a problem can have: when the detection stage cannot change the answer.

Every exposure's reach (X2) is at most that of the longest exposure allowed,
at the zenith of a dark night (no Moon, no twilight: each only brightens the
sky, and airmass only dims the source; D1), at the kilonova's brightest
moment while some candidate field is observable (inside one of the
problem's windows), in its brighter band: ``r_max``.  A pixel's
term of (X1) grows with the reach, and only pixels of the candidate fields
can be covered, so for every plan::

    E <= E_max = Σ_{l in the candidate fields} w_l · F_l(r_max)            (X7)

When the coverage plan's own expected detections are within ``min_gain``
of ``E_max`` (e.g. a source far beyond ZTF's reach, where both are ~0), no
detection plan can be preferred to it by more detections (R2), and the
detection stage is skipped.
"""

from __future__ import annotations

import numpy as np

from ...problem import PlanningProblem
from ...sky.skymap import SkyMap
from ...source.depth import ZTF_DEPTH, DepthModel, dark_zenith, limiting_magnitude
from ...source.detection import distance_cdf, reach_mpc
from ...source.kilonova import Kilonova

__all__ = ["detection_ceiling", "max_reach_mpc"]

#: Times (per day of horizon) at which the light curve is sampled for its brightest moment, besides its epochs.
SAMPLES_PER_DAY = 1440
#: The reach is widened by this factor (a margin on the sampled brightest moment).
REACH_MARGIN = 1.02


def max_reach_mpc(problem: PlanningProblem, kilonova: Kilonova, merger_age_days: float,
                  depth: DepthModel = ZTF_DEPTH) -> float:
    """``r_max`` (Mpc): the largest reach of any exposure of the problem (X7).

    Parameters
    ----------
    problem : PlanningProblem
        Filters, exposure (and exposure menu) and horizon.
    kilonova : Kilonova
        The source.
    merger_age_days : float
        The source's age at the horizon start (days).

    Returns
    -------
    float
        0 when no field is ever observable.
    depth : DepthModel
        Limiting-magnitude model.
    """
    cfg = problem.config
    longest = max([float(cfg.exposure_s), *map(float, cfg.exposure_menu_s)])
    w = problem.windows
    if w.start.size == 0:
        return 0.0
    t = np.linspace(0.0, cfg.horizon_s, max(2, int(SAMPLES_PER_DAY * cfg.horizon_s / 86400.0)) + 1)
    epochs = (np.asarray(kilonova.lightcurve.t_days, float) - merger_age_days) * 86400.0
    t = np.concatenate([t, epochs, w.start, w.end])  # the light curve's own epochs, every window's ends
    t = t[((t[:, None] >= w.start[None, :]) & (t[:, None] <= w.end[None, :])).any(axis=1)]  # when a field is up
    age = merger_age_days + t / 86400.0
    best = 0.0
    for band in dict.fromkeys(cfg.filters):
        brightest = float(np.min(kilonova.absolute_mag(band, age)))
        m5 = limiting_magnitude(np.array([band]), np.array([longest]), dark_zenith((1,)), depth)
        best = max(best, float(reach_mpc(m5, np.array([brightest]))[0]))
    return best * REACH_MARGIN


def detection_ceiling(problem: PlanningProblem, skymap: SkyMap, kilonova: Kilonova,
                      depth: DepthModel = ZTF_DEPTH) -> float:
    """``E_max`` (X7): no plan of ``problem`` has more expected detections (0 without distance layers)."""
    if not skymap.has_distance or skymap.event_time is None:
        return 0.0
    age = float((problem.start - skymap.event_time).to_value("day"))
    r_max = max_reach_mpc(problem, kilonova, age, depth)
    fp = problem.footprints
    pixels = np.unique(fp.indices)
    if r_max <= 0 or pixels.size == 0:
        return 0.0
    f = distance_cdf(skymap, pixels, np.full(pixels.size, r_max))
    return float(np.sum(skymap.prob[pixels] * f))
