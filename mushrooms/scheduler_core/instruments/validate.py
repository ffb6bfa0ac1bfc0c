"""Reading one parsed TOML table against its declared keys (:mod:`.schema`), one line per problem.

:func:`read_table` never stops at the first problem: it returns the values
it could read and appends to ``problems`` one line for each unknown key
(with the nearest known key, "did you mean"), missing key, value of the
wrong type and value out of its range.  Values shown in a message are cut
to a few dozen characters: a description may be a hostile file.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Mapping

from ..errors import InputError
from .schema import Key

__all__ = ["read_table", "shown", "type_name", "DescriptionError"]

#: The longest value shown in a message (characters).
SHOWN_MAX = 40


class DescriptionError(InputError):
    """A telescope description that cannot be used; ``problems`` holds one line each.

    ``str()`` is the problems joined by newlines, each line complete on its
    own (it names the file and the key).
    """

    def __init__(self, problems: list[str]) -> None:
        self.problems = tuple(problems)
        super().__init__("\n".join(self.problems))


def shown(value: Any) -> str:
    """A value as a message shows it: its TOML-ish form, cut to :data:`SHOWN_MAX` characters."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = f"{value:g}"
    elif isinstance(value, list) and all(isinstance(v, (str, int, float)) for v in value):
        text = "[" + ", ".join(shown(v) for v in value) + "]"
    elif isinstance(value, (dict, list)):
        text = type_name(value)
    else:
        text = repr(value)
    return text if len(text) <= SHOWN_MAX else text[:SHOWN_MAX - 3] + "..."


def type_name(value: Any) -> str:
    """The TOML name of a parsed value's type."""
    names = {bool: "a boolean", int: "an integer", float: "a number", str: "a string", list: "an array",
             dict: "a table"}
    return names.get(type(value), type(value).__name__)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number_problem(v: float, key: Key) -> str | None:
    """Why a number is refused (a phrase), or None."""
    if math.isnan(v):
        return "not a number (nan)"
    if math.isinf(v):
        return None if key.allow_inf else f"not finite; range {key.range_text()}"
    below = v <= key.lo if key.lo_open else v < key.lo
    above = v >= key.hi if key.hi_open else v > key.hi
    return f"outside its range {key.range_text()}" if below or above else None


_ELEMENT = {"numbers": "number", "integers": "integer", "strings": "string"}
_EXPECTED = {"number": "a number", "integer": "an integer", "string": "a string", "boolean": "a boolean",
             "numbers": "an array of numbers", "integers": "an array of integers", "strings": "an array of strings",
             "table": "a table", "tables": "an array of tables", "polygons": "an array of polygons [[x, y], ...]",
             "ids": "a table of names to integers"}


def _scalar_problem(v: Any, kind: str, key: Key) -> str | None:
    """Why one scalar of ``kind`` is refused, or None."""
    if kind == "number":
        return _number_problem(float(v), key) if _is_number(v) else f"expected a number, got {type_name(v)}"
    if kind == "integer":
        if not (isinstance(v, int) and not isinstance(v, bool)):
            return f"expected an integer, got {type_name(v)}"
        return _number_problem(float(v), key)
    if kind == "string":
        if not isinstance(v, str):
            return f"expected a string, got {type_name(v)}"
        if key.choices and v not in key.choices:
            return f"must be one of {', '.join(key.choices)}"
        return None
    if kind == "boolean":
        return None if isinstance(v, bool) else f"expected a boolean, got {type_name(v)}"
    raise AssertionError(kind)


def _polygons_problem(v: Any, key: Key) -> str | None:
    if not isinstance(v, list) or not v:
        return "expected a non-empty array of polygons [[x, y], ...]"
    for i, poly in enumerate(v):
        if not isinstance(poly, list) or not 3 <= len(poly) <= 64:
            return f"polygon {i}: expected 3 to 64 corners [x, y]"
        for corner in poly:
            if not (isinstance(corner, list) and len(corner) == 2 and all(_is_number(c) for c in corner)):
                return f"polygon {i}: a corner is not a pair of numbers [x, y]"
            if any(_number_problem(float(c), key) for c in corner):
                return f"polygon {i}: a corner outside {key.range_text()}"
    return None


def _value_problem(v: Any, key: Key) -> str | None:
    """Why a value is refused for ``key`` (one phrase), or None."""
    kind = key.kind
    if kind in _ELEMENT:
        if not isinstance(v, list):
            return f"expected {_EXPECTED[kind]}, got {type_name(v)}"
        for i, element in enumerate(v):
            why = _scalar_problem(element, _ELEMENT[kind], key)
            if why:
                return f"element {i}: {why}"
        return None
    if kind == "table":
        return None if isinstance(v, dict) else f"expected a table, got {type_name(v)}"
    if kind == "tables":
        ok = isinstance(v, list) and all(isinstance(t, dict) for t in v)
        return None if ok else f"expected an array of tables, got {type_name(v)}"
    if kind == "polygons":
        return _polygons_problem(v, key)
    if kind == "ids":
        if not isinstance(v, dict):
            return f"expected a table of names to integers, got {type_name(v)}"
        bad = [k for k, i in v.items() if _scalar_problem(i, "integer", key)]
        return f"{shown(bad[0])}: expected an integer in {key.range_text()}" if bad else None
    return _scalar_problem(v, kind, key)


def read_table(table: Any, schema: Mapping[str, Key], where: str, problems: list[str]) -> dict[str, Any]:
    """The valid values of ``table`` by ``schema``; a line in ``problems`` for each refused or missing one.

    Parameters
    ----------
    table : object
        The parsed TOML table (anything: a wrong type is a problem too).
    schema : mapping of str to Key
        The declared keys.
    where : str
        Prefix of every message (``ztf.toml: [site]``).
    problems : list of str
        Appended to.

    Returns
    -------
    dict
        Key -> value for every present and valid key.
    """
    if not isinstance(table, dict):
        problems.append(f"{where} expected a table, got {type_name(table)}")
        return {}
    out: dict[str, Any] = {}
    for name, value in table.items():
        key = schema.get(name)
        if key is None:
            near = difflib.get_close_matches(str(name), list(schema), n=1, cutoff=0.6)
            hint = f" (did you mean {near[0]!r}?)" if near else f" (known: {', '.join(schema)})"
            problems.append(f"{where} unknown key {shown(name)}{hint}")
            continue
        why = _value_problem(value, key)
        if why:
            problems.append(f"{where} {name} = {shown(value)}: {why}")
        else:
            out[name] = value
    for name, key in schema.items():
        if key.required and name not in table:
            unit = f", {key.unit}" if key.unit else ""
            problems.append(f"{where} missing key {name!r} ({key.meaning}{unit})")
    return out
