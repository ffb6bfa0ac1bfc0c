"""Where a study's results come from: hashes of inputs and settings, software versions, tracebacks.

Every record of the study (:mod:`.store`) carries the versions of the
worker that made it; map and result keys are hashes of the bytes and
settings they depend on.
"""

from __future__ import annotations

import functools
import hashlib
import json
import traceback
from pathlib import Path
from typing import Any

__all__ = ["VERSIONED", "TRACEBACK_FRAMES", "sha256_file", "digest", "software_versions", "traceback_summary",
           "future_traceback"]

#: Frames of a failed task's traceback kept in its record.
TRACEBACK_FRAMES = 4
#: Packages whose versions every record carries.
VERSIONED = ("mushrooms", "ligo.skymap", "highspy", "numpy", "astropy", "dask", "distributed", "lalsuite", "gwemopt")


def sha256_file(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def digest(obj: Any, n: int = 16) -> str:
    """Short stable hash of a JSON-able object."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:n]


@functools.lru_cache(maxsize=1)
def software_versions() -> dict[str, str]:
    """Versions of the packages a result depends on (``"-"`` when not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for name in VERSIONED:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "-"
    return out


def _frames(tb: Any, frames: int) -> list[str]:
    return [f"{Path(f.filename).name}:{f.lineno} in {f.name}: {(f.line or '').strip()}"
            for f in traceback.extract_tb(tb)[-frames:]]


def traceback_summary(exc: BaseException, frames: int = TRACEBACK_FRAMES) -> str:
    """The last ``frames`` frames of an exception's traceback and the exception, on one line."""
    return " | ".join(_frames(exc.__traceback__, frames) + [f"{type(exc).__name__}: {exc}"])[:2000]


def future_traceback(fut: Any) -> str:
    """:func:`traceback_summary` of a failed Dask future (empty when it cannot be read)."""
    try:
        tb = fut.traceback()
        exc = fut.exception()
        lines = _frames(tb, TRACEBACK_FRAMES) if tb is not None else []
        return " | ".join(lines + [f"{type(exc).__name__}: {exc}"])[:2000]
    except Exception:  # pragma: no cover - a traceback that cannot be read is not worth failing over
        return ""
