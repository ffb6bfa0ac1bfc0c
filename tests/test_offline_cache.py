"""The parsed Earth-orientation tables are kept in a private cache file and handed to astropy from there."""

from __future__ import annotations

import os

import numpy as np
import pytest
from astropy.time import Time
from astropy.utils import iers

from mushrooms.offline import configure_astropy_offline


@pytest.fixture
def fresh_astropy(monkeypatch, tmp_path):
    """astropy with no table loaded yet (restored after), the cache in tmp_path, parses counted."""
    monkeypatch.setenv("MUSHROOMS_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(iers.earth_orientation_table, "_value", None)
    parsed = []
    real_open = iers.IERS_Auto.open

    def counted_open(*args, **kwargs):
        parsed.append(1)
        return real_open(*args, **kwargs)

    monkeypatch.setattr(iers.IERS_Auto, "open", counted_open)
    return tmp_path / "cache", parsed


def test_the_second_command_reads_the_tables_from_the_cache_not_from_the_text_files(fresh_astropy, monkeypatch):
    cache, parsed = fresh_astropy
    configure_astropy_offline()
    files = list(cache.glob("earth-orientation-*.pickle"))
    assert parsed == [1] and len(files) == 1
    assert files[0].stat().st_mode & 0o077 == 0  # private
    first = Time("2026-05-01T03:00:00", scale="utc").delta_ut1_utc
    monkeypatch.setattr(iers.earth_orientation_table, "_value", None)  # a new process
    configure_astropy_offline()
    assert parsed == [1]  # not parsed again
    table = iers.earth_orientation_table.get()
    assert isinstance(table, iers.IERS_Auto) and len(table) > 10000
    assert Time("2026-05-01T03:00:00", scale="utc").delta_ut1_utc == first
    assert np.isfinite(first) and abs(first) < 0.9


def test_a_cache_file_others_can_write_or_a_damaged_one_is_not_used(fresh_astropy, monkeypatch):
    cache, parsed = fresh_astropy
    configure_astropy_offline()
    path, = cache.glob("earth-orientation-*.pickle")
    os.chmod(path, 0o666)  # someone else could have put anything there
    monkeypatch.setattr(iers.earth_orientation_table, "_value", None)
    configure_astropy_offline()
    assert parsed == [1, 1]  # parsed again, and the file rewritten private
    assert path.stat().st_mode & 0o077 == 0
    path.write_bytes(b"not a pickle")
    os.chmod(path, 0o600)
    monkeypatch.setattr(iers.earth_orientation_table, "_value", None)
    configure_astropy_offline()
    assert parsed == [1, 1, 1] and isinstance(iers.earth_orientation_table.get(), iers.IERS_Auto)


def test_a_cache_folder_that_cannot_be_written_costs_nothing_but_the_parse(fresh_astropy, monkeypatch, tmp_path):
    blocked = tmp_path / "file-not-folder"
    blocked.write_text("")
    monkeypatch.setenv("MUSHROOMS_CACHE_DIR", str(blocked / "cache"))
    _, parsed = fresh_astropy
    configure_astropy_offline()
    assert parsed == [1] and isinstance(iers.earth_orientation_table.get(), iers.IERS_Auto)
    assert iers.conf.auto_download is False
