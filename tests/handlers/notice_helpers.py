"""Real archived LVK notices (tests/data/notices) and helpers to mutate them in memory."""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import pytest

NOTICES = Path(__file__).resolve().parents[1] / "data" / "notices"


@lru_cache(maxsize=None)
def notice_bytes(rel: str) -> bytes:
    """Bytes of ``tests/data/notices/<rel>``."""
    return (NOTICES / rel).read_bytes()


def notice_dict(rel: str) -> dict[str, Any]:
    """A fresh dict of a JSON notice (safe to mutate)."""
    return json.loads(notice_bytes(rel))


def dumps(d: Any) -> bytes:
    return json.dumps(d).encode()


@pytest.fixture(scope="session")
def notices_dir() -> Path:
    return NOTICES
