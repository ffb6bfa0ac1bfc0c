"""Where a described mount can point: its hour-angle limit and its keep-out boxes.

(I4) a pointing at hour angle ``HA`` (deg, in [-180, 180)) and declination
``Dec`` is reachable when ``|HA| <= 15 ha_max_h`` and it lies in none of the
open boxes ``ha_min < HA < ha_max, dec_min < Dec < dec_max`` of
``[[limits.keep_out]]``.  ZTF's five rules (``sky/constraints.py``,
``mount_limits_ok``: the FFI, the service platform, the shutter's ears
on either side of the meridian, the pole) are five such boxes in
``ztf.toml``.  The airmass, Sun, Moon and declination-band limits are
applied where the planner applies them today (``sky/visibility.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .description import PointingLimits

__all__ = ["pointing_allowed"]


def pointing_allowed(limits: PointingLimits, ha_deg: ArrayLike, dec_deg: ArrayLike) -> np.ndarray:
    """(I4) The mount can point at (HA, Dec) (broadcasts).

    Parameters
    ----------
    limits : PointingLimits
        ``ha_max_h`` and the keep-out boxes.
    ha_deg : array_like
        Hour angle (deg, wrapped to [-180, 180)).
    dec_deg : array_like
        Declination (deg).

    Returns
    -------
    numpy.ndarray of bool
    """
    ha = np.asarray(ha_deg, float)
    dec = np.asarray(dec_deg, float)
    ok = np.abs(ha) <= limits.ha_max_h * 15.0
    for box in limits.keep_out:
        ok = ok & ~((ha > box.ha_min_deg) & (ha < box.ha_max_deg) & (dec > box.dec_min_deg) & (dec < box.dec_max_deg))
    return ok
