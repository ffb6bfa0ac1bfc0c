"""Which telescope a ``[scheduler] telescopes`` entry names, and its filters, without numpy (phase 2).

The configuration's checks (:mod:`..config_checks`) import only the standard
library: an entry is a shipped telescope's name (a file stem of
``data/telescopes/``) or the path of a description file (a ``.toml``, or
anything with a ``/``).  The full description is read by
:func:`.loader.load_description` when a plan is made.
"""

from __future__ import annotations

import difflib
import tomllib
from importlib import resources
from pathlib import Path

__all__ = ["DEFAULT_TELESCOPES", "shipped_telescopes", "is_path", "telescope_problem", "filter_names"]

#: The default of ``[scheduler] telescopes``: ZTF alone (a plan records the key only when it differs).
DEFAULT_TELESCOPES = ("ztf",)


def _folder() -> Path:
    return Path(str(resources.files("mushrooms.scheduler_core").joinpath("data", "telescopes")))


def shipped_telescopes() -> tuple[str, ...]:
    """Names of the shipped descriptions, sorted (``decam``, ``ls4``, ``winter``, ``ztf``)."""
    return tuple(sorted(p.stem for p in _folder().glob("*.toml")))


def is_path(entry: str) -> bool:
    """An entry naming a description file rather than a shipped telescope."""
    return "/" in entry or entry.endswith(".toml")


def telescope_problem(entry: object) -> str | None:
    """What is wrong with one ``telescopes`` entry (None: nothing), in one line with the nearest known name.

    Examples
    --------
    >>> telescope_problem("lsst4")
    "unknown telescope 'lsst4' (known: decam, ls4, winter, ztf; did you mean 'ls4'?)"
    >>> telescope_problem("ztf") is None
    True
    """
    if not isinstance(entry, str) or not entry:
        return f"telescopes must be names of telescopes or description files, got {entry!r}"
    shown = entry if len(entry) <= 60 else entry[:57] + "..."
    if is_path(entry):
        return None if Path(entry).expanduser().is_file() else f"telescope description {shown!r}: no such regular file"
    known = shipped_telescopes()
    if entry in known:
        return None
    near = difflib.get_close_matches(entry.lower(), known, n=1, cutoff=0.5)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    return f"unknown telescope {shown!r} (known: {', '.join(known)}{hint})"


def filter_names(entry: str) -> tuple[str, ...] | None:
    """The filters a telescope's description lists (its ``[filters]`` tables), None when unreadable.

    An unreadable or malformed file is reported in full when the description
    is loaded (:func:`.loader.load_description`); here it only skips the check.
    """
    path = Path(entry).expanduser() if is_path(entry) else _folder() / f"{entry}.toml"
    try:
        if path.stat().st_size > (1 << 20):
            return None
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    filters = table.get("filters")
    return tuple(filters) if isinstance(filters, dict) else None
