"""Kilonova source model: brightness per band at any time after the merger.

The tabulated light curves (:mod:`.lightcurves`, POSSIS grids) start at
0.202 d.  Before that a kilonova is not dark: it is a hot, optically thick
fireball expanding homologously.  This module extends a table to the first
hours with a *lower bound* on the flux that needs only two physical facts:

1. the photosphere sits in ejecta moving at a velocity that does not grow
   with time (it recedes in mass as the ejecta thin out), so its radius
   obeys ``R_ph(t) >= R_ph(t_a) * t / t_a`` for ``t <= t_a``;
2. the photospheric temperature does not grow with time (adiabatic
   expansion and a radioactive heating rate falling as ``t^-1.3``), so
   ``B_nu(T(t)) >= B_nu(T(t_a))`` in every band.

With ``L_nu = 4 pi^2 R_ph^2 B_nu(T)`` the specific luminosity at any
earlier time is at least ``(t / t_a)^2`` of that at ``t_a`` (the "expanding
fireball" rise, as for the first days of type Ia supernovae; Riess et al.
1999 AJ 118, 2675), i.e. in magnitudes::

    M_band(t) <= M_band(t_a) + 5 log10(t_a / t)     for 0 < t <= t_a     (K1)

Every tabulated epoch ``t_a`` up to :data:`EARLY_ANCHOR_MAX_DAYS` (1 d, while
the photosphere is still a blackbody in the ejecta and before the emission
turns nebular) is an anchor; the model magnitude is the brightest of the
table and all the bounds (K1).  Before the first epoch this is the only
information; inside the first day it also lifts the POSSIS epochs that
violate (K1) (the first grid epochs are photon-noise limited and, for the
NSBH grid, partly missing).  After the table ends (20 d) the source counts
as faded (``+inf``); at ``t <= 0`` (before the merger) it does not exist.

The bound is conservative: a hotter early photosphere, a free-neutron or
shock-cooling precursor, or a blue lanthanide-poor component (the first
hours of AT2017gfo were brighter than any rise from its later epochs)
would all make the source brighter than (K1).  Observations in the first
hours therefore count for *at least* what (K1) gives, never for nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .lightcurves import NOT_DETECTABLE, LightCurve, load_lightcurve

__all__ = ["EARLY_ANCHOR_MAX_DAYS", "Kilonova", "load_kilonova"]

#: Latest tabulated epoch (days after merger) used as an anchor of (K1).
EARLY_ANCHOR_MAX_DAYS = 1.0


@dataclass(frozen=True, eq=False)
class Kilonova:
    """A kilonova light curve valid from the merger on.

    Attributes
    ----------
    lightcurve : LightCurve
        Tabulated absolute magnitudes per band.
    anchor_max_days : float
        Tabulated epochs up to this time anchor the early rise (K1) (days).
    """

    lightcurve: LightCurve
    anchor_max_days: float = EARLY_ANCHOR_MAX_DAYS

    @property
    def name(self) -> str:
        """The light curve's label."""
        return self.lightcurve.name

    def absolute_mag(self, band: str, t_days: np.ndarray | float) -> np.ndarray:
        """Absolute AB magnitude at times since the merger.

        Parameters
        ----------
        band : str
            Band name as in the light-curve header (``g``, ``r``, ...).
        t_days : array_like
            Times since the merger (days).

        Returns
        -------
        numpy.ndarray
            Magnitude (mag), same shape as ``t_days``: the brightest of the
            interpolated table and the early-rise bounds (K1); ``+inf`` at
            ``t <= 0`` and after the table's last epoch.
        """
        t = np.asarray(t_days, dtype=float)
        table = self.lightcurve.absolute_mag(band, t)
        col = self.lightcurve.column(band)
        ta = self.lightcurve.t_days
        use = np.isfinite(col) & (ta <= self.anchor_max_days)
        if not use.any():
            return np.where(t > 0, table, NOT_DETECTABLE)
        ta, ma = ta[use], col[use]
        tt = t[..., None]
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = np.where((tt > 0) & (tt <= ta), ma + 5.0 * np.log10(ta / tt), math.inf)
        early = bound.min(axis=-1)
        return np.where(t > 0, np.minimum(table, early), NOT_DETECTABLE)

    def peak(self, band: str) -> tuple[float, float]:
        """Brightest point of a band: (magnitude, days since merger)."""
        return self.lightcurve.peak(band)


def load_kilonova(spec: str | Path | LightCurve, anchor_max_days: float = EARLY_ANCHOR_MAX_DAYS) -> Kilonova:
    """A kilonova from a packaged light-curve name, a file path or a table.

    Parameters
    ----------
    spec : str, pathlib.Path or LightCurve
        ``optimistic``, ``conservative``, ``nsbh``, a file, or a loaded table.
    anchor_max_days : float
        See :class:`Kilonova`.

    Returns
    -------
    Kilonova
    """
    lc = spec if isinstance(spec, LightCurve) else load_lightcurve(spec)
    return Kilonova(lightcurve=lc, anchor_max_days=anchor_max_days)
