"""Fixtures for scheduler_core tests: real sky maps, a real greedy plan."""

from __future__ import annotations

from pathlib import Path

import pytest

from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap

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
