"""Where mushrooms keeps its disk caches (the field footprints, the parsed Earth-orientation tables)."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["cache_dir"]


def cache_dir() -> Path:
    """``$MUSHROOMS_CACHE_DIR``, systemd's ``$CACHE_DIRECTORY``, else ``$XDG_CACHE_HOME/mushrooms`` or ``~/.cache/mushrooms``."""
    for var in ("MUSHROOMS_CACHE_DIR", "CACHE_DIRECTORY"):
        if os.environ.get(var):
            return Path(os.environ[var].split(":")[0])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mushrooms"
