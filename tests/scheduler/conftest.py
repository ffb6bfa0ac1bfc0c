"""Fixtures for scheduler_core tests: real sky maps, a real greedy plan."""

from __future__ import annotations

from pathlib import Path

import pytest

import healpy as hp
import numpy as np

from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
from mushrooms.scheduler_core.sky.skymap import SkyMap

DATA = Path(__file__).resolve().parents[1] / "data"
MAP_MULTIORDER = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
MAP_FLAT_RING = DATA / "skymaps" / "S200129m_cWB_RING.fits.gz"


@pytest.fixture(scope="session")
def greedy_config() -> PlanningConfig:
    return PlanningConfig(solver="greedy")


@pytest.fixture(scope="session")
def skymap_220722v(greedy_config):
    return read_skymap(MAP_MULTIORDER, nside=greedy_config.nside)


@pytest.fixture(scope="session")
def greedy_plan(skymap_220722v, greedy_config):
    return make_plan(skymap_220722v, greedy_config)


@pytest.fixture(scope="session")
def flat_map() -> SkyMap:
    """A uniform map at nside 64 (the checker's hand-built plans: coverage is the footprint's area)."""
    nside = 64
    prob = np.full(hp.nside2npix(nside), 1.0 / hp.nside2npix(nside))
    return SkyMap(prob=prob, nside=nside, event_time=None, object_id=None, distmu=None, distsigma=None,
                  distnorm=None, distmean=None, sha256="0" * 64, source="<flat>")
