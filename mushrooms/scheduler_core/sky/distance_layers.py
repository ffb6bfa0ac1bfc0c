"""Distance layers a map may carry but cannot use: treated as absent, said once.

A real map's DISTMU / DISTSIGMA / DISTNORM hold, per pixel, the parameters of
the distance ansatz (Singer et al. 2016), with ligo.skymap's convention
``(inf, 1, 0)`` for a pixel whose posterior the ansatz cannot represent.
A map whose layers are NaN, infinite or not positive *everywhere the
probability is* has no distance information at all: it used to pass
silently and give ``expected_detections`` 0.0, which reads as "this event
cannot be detected"; it is now a map without distance layers
(``expected_detections`` null) and one warning.  Single bad pixels become
ligo.skymap's ``(inf, 1, 0)``.  Done on the multi-order table, before
rasterisation: with all-NaN layers, ligo.skymap 2.5.4's ``derasterize`` merged a
flat NSIDE 64 map into its 12 base pixels holding 0.067 of the probability
(the sum check then refused the map).
"""

from __future__ import annotations

import logging

import numpy as np

__all__ = ["usable_distance_layers"]

log = logging.getLogger(__name__)


def usable_distance_layers(prob: np.ndarray, layers: dict[str, np.ndarray], name: str) -> dict[str, np.ndarray]:
    """The distance layers with unusable pixels set to ``(inf, 1, 0)``, or ``{}`` when no pixel is usable.

    Parameters
    ----------
    prob : numpy.ndarray
        Probability per pixel.
    layers : dict
        ``DISTMU`` (Mpc), ``DISTSIGMA`` (Mpc), ``DISTNORM`` (Mpc^-2) per pixel;
        empty or partial means no layers.
    name : str
        The map's name, for the warning.

    Returns
    -------
    dict
        The three layers, or an empty dict.
    """
    if not {"DISTMU", "DISTSIGMA", "DISTNORM"} <= set(layers):
        return {}
    mu, sigma, norm = (np.asarray(layers[c], float) for c in ("DISTMU", "DISTSIGMA", "DISTNORM"))
    good = np.isfinite(mu) & np.isfinite(sigma) & (sigma > 0) & np.isfinite(norm) & (norm > 0)
    weight = float(np.sum(prob[good]))
    if weight <= 0.0:
        log.warning("sky map %s: its distance layers hold no usable value (NaN, infinite or <= 0 wherever "
                    "the probability is): planned without distances, expected detections not computed", name)
        return {}
    if not np.all(good):
        mu, sigma, norm = mu.copy(), sigma.copy(), norm.copy()
        mu[~good], sigma[~good], norm[~good] = np.inf, 1.0, 0.0
    return {"DISTMU": mu, "DISTSIGMA": sigma, "DISTNORM": norm}

