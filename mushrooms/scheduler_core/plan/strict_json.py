"""JSON as RFC 8259 defines it: no ``NaN`` nor ``Infinity`` ever leaves the service.

Python's :func:`json.dumps` writes ``NaN`` and ``Infinity`` by default, which
are not JSON: a consumer's parser (JavaScript's ``JSON.parse``, Go, Java,
``jq``) refuses the whole document.  Every document the service writes (plan
files, queues, SkyPortal payloads, outbox and Kafka messages, the state's
copies) goes through :func:`dumps`, which refuses such a value with the path
of the first one instead of writing it.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = ["dumps", "non_finite_path"]


def non_finite_path(obj: Any, path: str = "") -> str | None:
    """Where the first NaN or infinity in a JSON-ready object sits (``metrics.coverage``), or None."""
    if isinstance(obj, float):
        return (path or "<top>") if not math.isfinite(obj) else None
    if isinstance(obj, dict):
        for k, v in obj.items():
            found = non_finite_path(v, f"{path}.{k}" if path else str(k))
            if found:
                return found
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            found = non_finite_path(v, f"{path}[{i}]")
            if found:
                return found
    return None


def dumps(obj: Any, **kwargs: Any) -> str:
    """:func:`json.dumps` with ``allow_nan=False``.

    Parameters
    ----------
    obj
        A JSON-ready object.
    **kwargs
        Passed on (``indent``, ``separators``, ``sort_keys``, ``default``).

    Raises
    ------
    ValueError
        ``not valid JSON: NaN or infinity at <path>`` when ``obj`` holds one.
    """
    try:
        return json.dumps(obj, allow_nan=False, **kwargs)
    except ValueError as exc:
        where = non_finite_path(obj)
        if where is None:
            raise
        raise ValueError(f"not valid JSON: NaN or infinity at {where}") from None
