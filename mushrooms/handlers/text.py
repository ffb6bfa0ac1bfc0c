"""Text from the outside made safe to log and to store.

A notice is JSON: it may carry strings that are valid JSON but not valid
Unicode (a lone surrogate such as ``"\\ud800"``), which SQLite and UTF-8 log
streams refuse, or control characters that break a one-line log.  Every
string that goes into a reason, a log line or the state passes through
:func:`storable` first.
"""

from __future__ import annotations

__all__ = ["storable"]

_CONTROL = {c: f"\\x{c:02x}" for c in range(32) if c not in (9,)} | {127: "\\x7f"}


def storable(text: object, limit: int | None = None) -> str:
    """``text`` as valid UTF-8 on one line, optionally cut to ``limit`` characters.

    Lone surrogates become ``\\udXXX`` escapes, control characters (newline
    included) ``\\xNN`` escapes; everything else is kept as is.

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
