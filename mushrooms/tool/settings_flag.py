"""``--set section.key=value`` (repeatable): change one configuration key for one run, without writing a file.

The value is read as a TOML value (``3``, ``2.5``, ``true``, ``"greedy"``,
``[30, 60]``); a bare word that is not TOML is taken as a string
(``--set scheduler.solver=greedy``).  Nested tables take more dots
(``--set scheduler.slew.readout_s=10``).  The keys are checked like the
file's: an unknown key or a value out of range is one line, exit 2.
"""

from __future__ import annotations

import argparse
import tomllib
from typing import Any, Iterable, Mapping


__all__ = ["add_set_option", "parse_set", "apply_sets"]


def add_set_option(p: argparse.ArgumentParser) -> None:
    """Add ``--set SECTION.KEY=VALUE`` (repeatable) to a tool's parser."""
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE", dest="set",
                   help="override one config key for this run (repeatable), e.g. --set scheduler.solver=greedy "
                        "--set scheduler.time_limit_s=4")


def parse_set(text: str) -> tuple[list[str], Any]:
    """``section.key=value`` as (path, value).

    Raises
    ------
    ValueError
        Without ``=`` or without a section and a key.
    """
    name, sep, raw = text.partition("=")
    path = [part.strip() for part in name.strip().split(".")]
    if not sep or len(path) < 2 or not all(path):
        raise ValueError(f"--set {text!r}: expected SECTION.KEY=VALUE (e.g. scheduler.solver=greedy)")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return path, value


def apply_sets(table: Mapping[str, Any], sets: Iterable[str]) -> dict[str, Any]:
    """The parsed TOML ``table`` with every ``--set`` applied (a new dict; ``table`` is unchanged)."""
    merged: dict[str, Any] = {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in table.items()}
    for text in sets:
        path, value = parse_set(text)
        node = merged
        for depth, part in enumerate(path[:-1]):
            child = node.get(part, {})
            if not isinstance(child, Mapping):  # `slew = 1` in the file is an error, not a table to fill
                from ..scheduler_core.tables import shown_value  # here: --help must load no scheduler module

                raise ValueError(f"--set {text}: {'.'.join(path[:depth + 1])} is not a table (it is "
                                 f"{shown_value(child)}): correct the file")
            child = dict(child)
            node[part] = child
            node = child
        node[path[-1]] = value
    return merged
