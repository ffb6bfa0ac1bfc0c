"""Shared test setup: offline astropy, a private footprint cache, data paths."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
DATA = TESTS / "data"


def pytest_configure(config: pytest.Config) -> None:
    from astropy.utils import iers

    iers.conf.auto_download = False  # no network, ever
    iers.conf.auto_max_age = None
    if "MUSHROOMS_CACHE_DIR" not in os.environ:
        cache = Path(config.rootpath) / ".pytest_cache" / "mushrooms-footprints"
        os.environ["MUSHROOMS_CACHE_DIR"] = str(cache)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """tests/data."""
    return DATA
