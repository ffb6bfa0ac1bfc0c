"""Parsed TOML tables into frozen config dataclasses: the one helper every section type is built on.

A leaf: imports only the standard library, so a layer that owns a section
(``[scheduler]`` here, ``[policy]`` in :mod:`mushrooms.handlers.policy`,
``[daemon]``/``[kafka]``/``[outbound]``/``[submit]`` in :mod:`mushrooms.daemon`,
``[export]`` in :mod:`.plan.exports`) reads its table without importing
anything heavy, and the tool layer's config loader
(:mod:`mushrooms.tool.config`) assembles them.

:func:`dataclass_from_table` refuses unknown keys, values of the wrong TOML
type and values outside the :class:`~.ranges.Range` a field declares
(:func:`check_table`, read from the field's metadata), each with a
:class:`TableError` naming the section, key and value.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import difflib
import types
import typing
from typing import Any, Mapping, Protocol

__all__ = ["TableError", "dataclass_from_table", "check_table", "check_value", "unknown_names", "toml_type",
           "shown_value", "is_table_hint"]

#: Longest value (characters of its ``repr``) a message shows; a longer one is cut with ``...``.
MAX_SHOWN = 80


class TableError(ValueError):
    """A value of a config table is refused; ``str()`` is the one-line message.

    Attributes
    ----------
    section : str
        The table (``scheduler``, ``scheduler.slew``, ``daemon`` ...).
    key : str or None
        The refused key (None for several unknown keys: see ``keys``).
    value : object
        The refused value (None when not one value).
    expected : str or None
        What the key takes (``an integer``, a range ``[1, 600] s``), when known.
    keys : tuple of str
        The unknown keys, for an unknown-key error.
    """

    def __init__(self, message: str, *, section: str, key: str | None = None, value: Any = None,
                 expected: str | None = None, keys: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.section, self.key, self.value, self.expected, self.keys = section, key, value, expected, keys


class _Bounds(Protocol):
    """What :func:`check_value` needs of a :class:`~.ranges.Range`."""

    def problem(self, value: Any) -> str | None: ...


def dataclass_from_table(cls: type, table: Mapping[str, Any], section: str) -> Any:
    """Build a frozen config dataclass from a parsed TOML table.

    Unknown keys are an error naming them; TOML arrays become tuples.

    Parameters
    ----------
    cls : type
        The dataclass.
    table : mapping
        The parsed ``[section]`` table.
    section : str
        Its name, for the error message.

    Raises
    ------
    TableError
        ``unknown [section] key(s): ...`` (with a ``did you mean`` for a
        near miss), a value of the wrong type (a table where a table belongs,
        and nothing else there) or outside the range its field declares
        (:mod:`.ranges`).
    ValueError
        The dataclass's own check.
    """
    if not isinstance(table, Mapping):
        raise TableError(f"[{section}] = {shown_value(table)}: expected a table, got {toml_type(table)}",
                         section=section, value=table, expected="a table")
    fields = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(table) - set(fields))
    if unknown:
        raise TableError(f"unknown [{section}] key(s): {unknown_names(unknown, fields)}", section=section,
                         key=unknown[0] if len(unknown) == 1 else None, keys=tuple(unknown))
    hints = typing.get_type_hints(cls)
    for key, value in table.items():
        expected = _type_name(hints[key])
        if dataclasses.is_dataclass(hints[key]):  # name the table and its keys: `[scheduler.slew] readout_s = 8`
            keys = ", ".join(f.name for f in dataclasses.fields(hints[key]))
            expected = f"a table ([{section}.{key}] with the keys {keys})"
        if expected is not None and not _has_type(value, hints[key]):
            raise TableError(f"[{section}] {key} = {shown_value(value)}: expected {expected}, got {toml_type(value)}",
                             section=section, key=key, value=value, expected=expected)
    check_table(cls, table, section)
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in table.items()}
    return cls(**values)


def check_value(section: str, key: str, value: Any, rng: _Bounds) -> None:
    """Refuse one value outside ``rng`` (arrays: every element).

    Raises
    ------
    TableError
        ``[section] key = value: outside its range [lo, hi] unit``.
    """
    values = value if isinstance(value, (list, tuple)) else [value]
    for v in values:
        why = rng.problem(v)
        if why is not None:
            shown = f"{v:g}" if isinstance(v, float) else repr(v)
            where = f"{key} element" if isinstance(value, (list, tuple)) else key
            raise TableError(f"[{section}] {where} = {shown}: {why}", section=section, key=key, value=v,
                             expected=str(rng))


def check_table(cls: type, table: Mapping[str, Any], section: str) -> None:
    """Refuse the first value of a parsed table outside its field's declared range (field metadata ``range``)."""
    ranges = {f.name: r for f in dataclasses.fields(cls) if (r := f.metadata.get("range")) is not None}
    for key, value in table.items():
        if key in ranges and value is not None:
            check_value(section, key, value, ranges[key])


def unknown_names(unknown: list[str], known: list[str]) -> str:
    """The unknown names, each with its nearest known one when close enough: ``slwe (did you mean slew?)``."""
    said = []
    for name in unknown[:10]:  # a hostile --set's thousand keys, or one of 100 kB, stay one short line
        shown = name if len(name) <= MAX_SHOWN else name[:MAX_SHOWN - 3] + "..."
        near = difflib.get_close_matches(name, known, n=1, cutoff=0.6) if len(name) <= MAX_SHOWN else []
        said.append(f"{shown} (did you mean {near[0]}?)" if near else shown)
    return ", ".join(said) + (f" and {len(unknown) - 10} more" if len(unknown) > 10 else "")


def toml_type(value: Any) -> str:
    """The TOML name of a parsed value's type."""
    if isinstance(value, Mapping):
        return "table"
    names = {bool: "boolean", int: "integer", float: "float", str: "string", list: "array", tuple: "array"}
    return names.get(type(value), type(value).__name__)


def shown_value(value: Any) -> str:
    """``repr(value)`` for a message (a boolean as TOML writes it), at most :data:`MAX_SHOWN` characters (a huge
    ``--set`` stays one short line)."""
    text = str(value).lower() if isinstance(value, bool) else repr(value)
    return text if len(text) <= MAX_SHOWN else text[:MAX_SHOWN - 3] + "..."


def is_table_hint(hint: Any) -> bool:
    """True when a field's annotation takes a table: a nested config dataclass or a mapping."""
    origin = typing.get_origin(hint) or hint
    return dataclasses.is_dataclass(hint) or (isinstance(origin, type) and issubclass(origin, collections.abc.Mapping))


def _has_type(value: Any, hint: Any) -> bool:
    """True when a parsed TOML value fits a dataclass field's annotation."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_has_type(value, h) for h in typing.get_args(hint))
    if hint is type(None):
        return value is None
    if dataclasses.is_dataclass(hint):  # a nested table, or the dataclass a caller built from it
        return isinstance(value, (Mapping, hint))
    if is_table_hint(hint):  # a table of names (``[bench.maglim]``): its dataclass checks the entries
        return isinstance(value, Mapping)
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is str:
        return isinstance(value, str)
    if origin is tuple:
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        return isinstance(value, (list, tuple)) and all(_has_type(v, args[0]) for v in value) if args else True
    return True  # anything else (``Any``): the dataclass checks it


#: Readable names of the scalar annotations, one and many.
_SCALAR_NAMES = {bool: ("a boolean", "booleans"), int: ("an integer", "integers"), float: ("a number", "numbers"),
                 str: ("a string", "strings")}


def _type_name(hint: Any) -> str | None:
    """Readable name of an annotation for error messages (None: not checked here)."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        names = [_type_name(h) for h in typing.get_args(hint) if h is not type(None)]
        return None if None in names else " or ".join(n for n in names if n)
    if origin is tuple:
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        if not args:
            return "an array"
        many = _SCALAR_NAMES.get(args[0], (None, None))[1]
        return f"an array of {many}" if many else "an array"
    if is_table_hint(hint):
        return "a table"
    return _SCALAR_NAMES.get(hint, (None, None))[0]
