"""Fixtures of the pipeline/replay tests."""

from __future__ import annotations

import pytest

from mushrooms.daemon.state.store import Store


@pytest.fixture
def store(tmp_path):
    """A fresh SQLite state store in the test's directory."""
    s = Store(tmp_path / "state.sqlite")
    yield s
    s.close()
