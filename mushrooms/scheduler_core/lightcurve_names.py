"""The light curves shipped with the package, by name: a leaf (no numpy), read by ``[scheduler]``'s check.

:mod:`.source.lightcurves` reads the files; :class:`~mushrooms.scheduler_core.config.PlanningConfig`
only needs the names (``detection_lightcurve``), so loading the configuration imports no numpy.
"""

from __future__ import annotations

from typing import Mapping

__all__ = ["PAPER_LIGHTCURVES"]

#: Named light curves shipped with the package: name -> file in data/lightcurves.
PAPER_LIGHTCURVES: Mapping[str, str] = {
    "optimistic": "Bulla_mejdyn0.005_mejwind0.110_phi45_45.6.dat",
    "conservative": "Bulla_BNS_mejdyn0.010_mejwind0.010_phi45_45.6.dat",
    "nsbh": "Bulla_NSBH_mejdyn0.020_mejwind0.060_phi30_45.6.dat",
}
