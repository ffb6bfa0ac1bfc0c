"""Documented ranges of numeric settings, declared once beside each field.

A config dataclass declares a numeric field with :func:`setting`, which keeps
the default and attaches a :class:`Range` as field metadata::

    @dataclass(frozen=True)
    class DaemonConfig:
        heartbeat_s: float = setting(30.0, 1, 600, "s")

and :func:`~mushrooms.scheduler_core.tables.dataclass_from_table` refuses a
table value outside it (:func:`~mushrooms.scheduler_core.tables.check_table`,
re-exported here), with one line naming the key, the value and the range.  The ranges are what an operator may *configure*;
a notebook building a dataclass by hand is held only to finite numbers
(:func:`require_finite`), so unit tests may still build a one-pixel problem.
``docs/configuration.md`` and the comments of ``config.toml`` show the same
ranges (``tests/test_config_ranges.py`` keeps the three in step).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

from .tables import TableError, check_table, check_value

__all__ = ["Range", "setting", "range_of", "ranges_of", "check_table", "check_value", "require_finite"]


def _num(x: float) -> str:
    """A bound as an operator writes it (integers without a decimal point)."""
    if float(x).is_integer() and abs(x) < 1e15:
        return str(int(x))
    return f"{x:g}"


@dataclass(frozen=True)
class Range:
    """The values a numeric setting may take.

    Attributes
    ----------
    lo, hi : float
        Bounds (in the setting's unit).
    unit : str
        Unit shown after the interval (``s``, ``deg``, ``h`` ...), or ``""``.
    lo_open, hi_open : bool
        The bound itself is excluded.
    power_of_two : bool
        The value must also be a power of two (HEALPix NSIDE).
    off : float or None
        One value outside the interval that is accepted because it means
        "disabled" or "automatic" (e.g. ``0``).
    why : str
        Short reason for the bounds (for the docs table).
    """

    lo: float
    hi: float
    unit: str = ""
    lo_open: bool = False
    hi_open: bool = False
    power_of_two: bool = False
    off: float | None = None
    why: str = ""

    def __str__(self) -> str:
        text = f"{'(' if self.lo_open else '['}{_num(self.lo)}, {_num(self.hi)}{')' if self.hi_open else ']'}"
        if self.unit:
            text += f" {self.unit}"
        if self.power_of_two:
            text += ", a power of 2"
        if self.off is not None:
            text += f", or {_num(self.off)}"
        return text

    def problem(self, value: Any) -> str | None:
        """Why ``value`` is refused (a phrase), or None when it is in range."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return None  # the type check names it
        if not math.isfinite(value):
            return f"not a finite number; range {self}"
        if self.off is not None and value == self.off:
            return None
        below = value <= self.lo if self.lo_open else value < self.lo
        above = value >= self.hi if self.hi_open else value > self.hi
        because = f" ({self.why})" if self.why else ""
        if below or above:
            return f"outside its range {self}{because}"
        if self.power_of_two and (int(value) != value or int(value) & (int(value) - 1)):
            return f"not a power of 2; range {self}{because}"
        return None


def setting(default: Any, lo: float, hi: float, unit: str = "", *, lo_open: bool = False, hi_open: bool = False,
            power_of_two: bool = False, off: float | None = None, why: str = "") -> Any:
    """A dataclass field with a default and a documented :class:`Range`.

    Parameters
    ----------
    default
        The built-in default (must lie in the range; None for "unset").
    lo, hi : float
        Bounds, inclusive unless ``lo_open`` / ``hi_open``.
    unit : str
        Unit of the value, shown with the range.
    power_of_two : bool
        Also require a power of two.
    off : float, optional
        A value outside the range accepted as "disabled" / "automatic".
    why : str
        Why these bounds (one phrase, shown in ``docs/configuration.md``).

    Returns
    -------
    dataclasses.Field
        To assign as the field's default in a (frozen) dataclass.
    """
    rng = Range(float(lo), float(hi), unit, lo_open, hi_open, power_of_two, off, why)
    if default is not None and not isinstance(default, (tuple, list)):
        assert rng.problem(default) is None, f"default {default!r} outside {rng}"
    return dataclasses.field(default=default, metadata={"range": rng})


def range_of(f: dataclasses.Field) -> Range | None:
    """The :class:`Range` a field was declared with, or None."""
    return f.metadata.get("range")


def ranges_of(cls: type) -> dict[str, Range]:
    """Field name -> :class:`Range` of every ranged field of a dataclass, in declaration order."""
    return {f.name: r for f in dataclasses.fields(cls) if (r := range_of(f)) is not None}


def require_finite(obj: Any, section: str) -> None:
    """Refuse NaN and infinities in any numeric field of a dataclass instance (arrays included).

    Called from ``__post_init__``: a hand-built config may leave the
    documented ranges, never the finite numbers.

    Raises
    ------
    TableError
        ``[section] key = nan: not a finite number``.
    """
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        for v in value if isinstance(value, (list, tuple)) else [value]:
            if isinstance(v, float) and not math.isfinite(v):
                raise TableError(f"[{section}] {f.name} = {v:g}: not a finite number", section=section,
                                 key=f.name, value=v, expected="a finite number")


def markdown_table(sections: Mapping[str, type]) -> str:
    """The documented ranges as a Markdown table (``docs/configuration.md``).

    Parameters
    ----------
    sections : mapping
        Section name (``scheduler``, ``scheduler.slew`` ...) -> its dataclass.

    Returns
    -------
    str
        One row per ranged key: section, key, default, range, why.
    """
    rows = ["| section | key | default | range | why these bounds |", "|---|---|---|---|---|"]
    for section, cls in sections.items():
        for f in dataclasses.fields(cls):
            rng = range_of(f)
            if rng is None:
                continue
            default = f.default
            shown = "unset" if default is None else (
                "[" + ", ".join(map(str, default)) + "]" if isinstance(default, tuple) else repr(default))
            rows.append(f"| `[{section}]` | `{f.name}` | {shown} | {rng} | {rng.why} |")
    return "\n".join(rows) + "\n"
