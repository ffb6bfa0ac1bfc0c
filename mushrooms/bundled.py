"""Files bundled with the package: the demo sky map and the demo notice (no network needed)."""

from __future__ import annotations

from importlib import resources

__all__ = ["DEMO_SKYMAP", "DEMO_NOTICE", "demo_skymap_path", "demo_notice_path"]

#: The bundled demo sky map (mock BNS MS181101ab, LVK user guide example), in ``mushrooms.scheduler_core``.
DEMO_SKYMAP = "data/MS181101ab_bayestar.multiorder.fits"

#: The bundled demo notice (mock BNS MS260605l, PRELIMINARY, H1/L1/V1, ~8 deg2), in ``mushrooms``.
DEMO_NOTICE = "data/demo/MS260605l-preliminary.json"


def demo_skymap_path() -> str:
    """Path of the bundled demo sky map."""
    return str(resources.files("mushrooms.scheduler_core").joinpath(DEMO_SKYMAP))


def demo_notice_path() -> str:
    """Path of the bundled demo notice."""
    return str(resources.files("mushrooms").joinpath(DEMO_NOTICE))
