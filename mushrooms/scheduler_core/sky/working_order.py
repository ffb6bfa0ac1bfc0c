"""A sky map accumulated at one working HEALPix order, chunk by chunk (the streaming reader's arithmetic).

Source pixels arrive as NESTED indices at their own orders (a multi-order
map's rows, or a flat map's pixels) and are added vectorised per chunk: a
pixel at the working order is copied, a coarser one is shared among its
children with its distance layers, finer ones add their probability and
their probability-weighted conditional distance moments to their ancestor
(``np.bincount``), and :meth:`WorkingOrder.result` turns merged moments
back into ligo.skymap's distance ansatz. The reading itself (headers,
refusals, chunks) is :mod:`.skymap`'s.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WorkingOrder", "DIST_COLUMNS"]

#: The distance-ansatz columns of an LVK sky map (Mpc, Mpc, Mpc^-2).
DIST_COLUMNS = ("DISTMU", "DISTSIGMA", "DISTNORM")


class WorkingOrder:
    """Probability and distance layers accumulated at the working order, chunk by chunk.

    A working pixel is either *direct* (one source pixel at the working
    order, or a coarser one shared among its children: its layers copied)
    or *merged* (finer source pixels: probability and the probability-
    weighted first and second conditional distance moments summed).
    """

    def __init__(self, order: int, with_distance: bool):
        self.order = order
        self.npix = 12 * 4**order
        self.prob = np.zeros(self.npix)
        self.with_distance = with_distance
        if with_distance:
            self.layers = [np.full(self.npix, np.inf), np.ones(self.npix), np.zeros(self.npix)]
            self.merged = np.zeros(self.npix, bool)
            self.moment1 = np.zeros(self.npix)
            self.moment2 = np.zeros(self.npix)
            self.mixed = np.zeros(self.npix, bool)  # merged children whose (DISTMU, DISTSIGMA) differ
            self.first = [np.zeros(self.npix), np.zeros(self.npix), np.zeros(self.npix)]  # one child's layers

    def add(self, order: np.ndarray | int, ipix: np.ndarray, prob: np.ndarray,
            layers: list[np.ndarray] | None) -> None:
        """Add source pixels (NESTED ``ipix`` at ``order``, probability ``prob``, layers mu/sigma/norm)."""
        order = np.broadcast_to(np.asarray(order, np.int64), ipix.shape)
        for part, pick in ((self._same, order == self.order), (self._coarse, order < self.order),
                           (self._fine, order > self.order)):
            if np.any(pick):
                part(order[pick], ipix[pick], prob[pick], None if layers is None else [x[pick] for x in layers])

    def _same(self, order, ipix, prob, layers) -> None:
        self.prob[ipix] += prob
        if self.with_distance:
            for out, values in zip(self.layers, layers):
                out[ipix] = values

    def _coarse(self, order, ipix, prob, layers) -> None:
        shift = 2 * (self.order - order)
        n = np.int64(1) << shift  # children per pixel
        start = np.repeat(ipix << shift, n)
        rank = np.arange(start.size, dtype=np.int64) - np.repeat(np.cumsum(n) - n, n)
        self._same(None, start + rank, np.repeat(prob / n, n),
                   None if layers is None else [np.repeat(x, n) for x in layers])

    def _fine(self, order, ipix, prob, layers) -> None:
        target = ipix >> (2 * (order - self.order))
        lo, hi = int(target.min()), int(target.max())
        span, local = slice(lo, hi + 1), target - lo

        def add(acc: np.ndarray, weights: np.ndarray) -> None:
            acc[span] += np.bincount(local, weights, minlength=hi - lo + 1)

        add(self.prob, prob)
        if not self.with_distance:
            return
        from ligo.skymap.distance import parameters_to_moments

        mu, sigma, norm = layers
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            mean, std, _ = parameters_to_moments(mu, sigma)
        bad = ~(np.isfinite(mu) & np.isfinite(sigma))
        mean[bad] = std[bad] = np.nan
        with np.errstate(invalid="ignore"):
            add(self.moment1, prob * mean)
            add(self.moment2, prob * (std**2 + mean**2))
        new = ~self.merged[target]
        self.merged[target] = True
        for ref, values in zip(self.first, (mu, sigma, norm)):
            ref[target[new]] = values[new]  # any one child's layers
        differ = bad | (mu != self.first[0][target]) | (sigma != self.first[1][target])
        self.mixed[target[differ]] = True

    def result(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Probability per working pixel and the distance layers (empty dict without distance)."""
        if not self.with_distance:
            return self.prob, {}
        from ligo.skymap.distance import moments_to_parameters

        mu, sigma, norm = self.layers
        # children all alike: their layers (what ligo.skymap's derasterize makes of equal siblings, even
        # where the probability is 0 and the moments are undefined)
        keep = self.merged & ~self.mixed
        for out, ref in zip(self.layers, self.first):
            out[keep] = ref[keep]
        solve = self.merged & ~keep
        if np.any(solve):
            with np.errstate(invalid="ignore", divide="ignore"):
                w = self.prob[solve]
                first = self.moment1[solve] / w
                std = np.sqrt(self.moment2[solve] / w - first**2)
                mu[solve], sigma[solve], norm[solve] = moments_to_parameters(first, std)
        return self.prob, dict(zip(DIST_COLUMNS, self.layers))
