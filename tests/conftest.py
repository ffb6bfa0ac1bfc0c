"""Shared test setup: offline astropy, a per-session footprint cache, data paths."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
DATA = TESTS / "data"
_CACHE_KEY = pytest.StashKey[Path]()


def pytest_configure(config: pytest.Config) -> None:
    from astropy.utils import iers

    iers.conf.auto_download = False  # no network, ever
    iers.conf.auto_max_age = None
    # A fresh footprint cache for every session: a disk cache left by an
    # earlier run (keyed on inputs, not on code) would hide a footprint bug.
    cache = Path(tempfile.mkdtemp(prefix="mushrooms-footprints-"))
    config.stash[_CACHE_KEY] = cache
    os.environ["MUSHROOMS_CACHE_DIR"] = str(cache)


def pytest_unconfigure(config: pytest.Config) -> None:
    cache = config.stash.get(_CACHE_KEY, None)
    if cache is not None:
        shutil.rmtree(cache, ignore_errors=True)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """tests/data."""
    return DATA
