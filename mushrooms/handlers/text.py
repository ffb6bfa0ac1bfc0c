"""Text from the outside made safe to log and to store.

A notice is JSON: it may carry strings that are valid JSON but not valid
Unicode (a lone surrogate such as ``"\\ud800"``), which SQLite and UTF-8 log
streams refuse, or control characters that break a one-line log or drive
the terminal that shows it: C0 and C1 controls (U+0080-U+009F, whose
U+009B is the 8-bit CSI), Unicode's bidirectional embeddings, overrides and
isolates (U+202E shows ``exe.txt`` for ``txt.exe``) and line separators.
Every string that goes into a reason, a log line, the state or a summary
an observer reads passes through :func:`storable` first.
"""

from __future__ import annotations

__all__ = ["storable"]

#: Characters never shown raw: C0 controls but tab, DEL, C1 controls (``\\xNN``); the bidirectional marks,
#: embeddings, overrides and isolates, and the line and paragraph separators (``\\uNNNN``).
_CONTROL = {c: f"\\x{c:02x}" for c in [*range(32), *range(127, 160)] if c != 9} | {
    c: f"\\u{c:04x}" for c in (0x061C, 0x200E, 0x200F, *range(0x202A, 0x202F), *range(0x2066, 0x206A), 0x2028, 0x2029)}


def storable(text: object, limit: int | None = None) -> str:
    """``text`` as valid UTF-8 on one line, optionally cut to ``limit`` characters.

    Lone surrogates become ``\\udXXX`` escapes, C0 and C1 control characters
    (newline included) ``\\xNN`` escapes, bidirectional controls and line
    separators ``\\uNNNN`` escapes; everything else is kept as is.

    Parameters
    ----------
    text : object
        Usually a str; anything else is formatted with ``str()``.
    limit : int, optional
        Longest result (characters); longer text ends with ``...``.

    Returns
    -------
    str
    """
    s = text if isinstance(text, str) else str(text)
    s = s.encode("utf-8", "backslashreplace").decode("utf-8").translate(_CONTROL)
    if limit is not None and len(s) > limit:
        s = s[: max(limit - 3, 0)] + "..."
    return s
