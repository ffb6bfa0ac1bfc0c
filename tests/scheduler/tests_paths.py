"""Paths of the test sky maps (importable from the scheduler tests)."""

from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data"
MAP_220722V = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
MAP_FLAT_RING = DATA / "skymaps" / "S200129m_cWB_RING.fits.gz"
