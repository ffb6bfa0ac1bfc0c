"""No network for astropy: Earth-orientation tables come from the installed astropy-iers-data package.

Every command and the service call :func:`configure_astropy_offline` before
any time or coordinate work, so a plan never stalls on (or fails for) a
download at 3 a.m.
"""

from __future__ import annotations

__all__ = ["configure_astropy_offline"]


def configure_astropy_offline() -> None:
    """Never let astropy try to download Earth-orientation tables (no network)."""
    from astropy.utils import iers

    iers.conf.auto_download = False
    iers.conf.auto_max_age = None
