"""Text made harmless for a chat message (Slack's incoming webhooks and the chat tools that copy them).

A message to the observer on call carries text from outside: Kowalski's
refusal, an error, a notice's identifiers.  Said verbatim it could ping a
whole channel (``<!channel>``, ``@here``), hide a link behind a friendly
label (``<https://evil.example/login|log in>``, ``[log in](https://...)``),
or reorder and hide what the reader sees (U+202E RIGHT-TO-LEFT OVERRIDE,
zero-width characters, terminal escapes).  :func:`chat_safe` neutralises
all of it, so the message reads as what it is:

- ``&``, ``<`` and ``>`` become ``&amp;``, ``&lt;`` and ``&gt;``: Slack's own
  escaping (https://api.slack.com/reference/surfaces/formatting#escaping),
  which turns every ``<...>`` control sequence (mentions, links with labels)
  into plain text that still shows the characters;
- ``@channel``, ``@here``, ``@everyone`` and ``@all`` (mentions in plain text
  for Mattermost, Discord, Rocket.Chat) become ``@ channel`` ...;
- a Markdown link ``[label](url)`` becomes ``[label] (url)`` (no link);
- line breaks and tabs become spaces (a message is one paragraph);
- other control characters (C0, DEL, C1), format characters (bidi
  embeddings, overrides and isolates, zero-width ones, the BOM, tags), lone
  surrogates and unassigned code points become visible escapes (``\\u202e``);
- text longer than ``limit`` is cut and ends with ``...``.

A bare URL stays as it is: it shows where it leads.
"""

from __future__ import annotations

import re
import unicodedata

__all__ = ["chat_safe", "CHAT_LIMIT"]

#: Longest message text (characters); Slack advises at most 4000 (its hard limit is 40 000).
CHAT_LIMIT = 3000

_MARKUP = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;"})
_BREAKS = re.compile(r"[\t\n\r\v\f\u2028\u2029]+")
_BROADCAST = re.compile(r"(?i)(?<![\w.+-])@(channel|here|everyone|all)\b")  # not an e-mail address
_MD_LINK = re.compile(r"\]\s*\(")
#: Unicode categories never said as they are: control, format, surrogate, unassigned, private use.
_HIDDEN = {"Cc", "Cf", "Cs", "Cn", "Co"}


def _visible(ch: str) -> str:
    code = ord(ch)
    if unicodedata.category(ch) not in _HIDDEN:
        return ch
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def chat_safe(text: object, limit: int = CHAT_LIMIT) -> str:
    """``text`` with its chat markup and its hidden characters neutralised (see the module), at most ``limit`` long.

    Parameters
    ----------
    text : object
        Usually a str; anything else is formatted with ``str()``.
    limit : int
        Longest result (characters); longer text is cut and ends with ``...``.

    Returns
    -------
    str

    Examples
    --------
    >>> chat_safe("<!channel> log in: <https://evil.example|here> @here \\u202etxt")
    '&lt;!channel&gt; log in: &lt;https://evil.example|here&gt; @ here \\\\u202etxt'
    """
    s = text if isinstance(text, str) else str(text)
    if len(s) > 4 * limit:  # never walk a huge text character by character
        s = s[: 4 * limit]
    s = _BREAKS.sub(" ", s)
    s = "".join(map(_visible, s)) if not s.isascii() or not s.isprintable() else s
    s = _MD_LINK.sub("] (", _BROADCAST.sub(r"@ \1", s.translate(_MARKUP)))
    if len(s) > limit:
        s = s[: max(limit - 3, 0)] + "..."
    return s
