"""Secrets never in configured URLs, and every form of them out of what is logged.

A secret comes from the environment or a systemd credential, never from a URL:
:func:`refuse_url_credentials` refuses ``http://user:password@host`` where a
URL is configured (``[submit] url``, ``[loop] executed_source``, ``mushrooms
queue --url``).  :func:`redact` blanks a secret in text a server sent back or
an error message: the secret itself, its percent-encoded form, its HTTP basic
form (``base64(secret)``, as an ``Authorization: Basic`` header echoed by a
server carries it) and any ``user:password@`` of a URL in the text.
"""

from __future__ import annotations

import base64
import re
from urllib.parse import quote, urlsplit

__all__ = ["refuse_url_credentials", "redact", "strip_userinfo"]

#: ``scheme://user:password@`` (or ``scheme://user@``) inside any text.
_USERINFO = re.compile(r"(?i)\b([a-z][a-z0-9+.-]*://)[^/\s@]+@")


def refuse_url_credentials(url: str, where: str, hint: str) -> None:
    """Raise ``ValueError`` (one line, the URL without its credentials) when ``url`` has ``user[:password]@``.

    Parameters
    ----------
    url : str
    where : str
        The setting, e.g. ``[loop] executed_source``.
    hint : str
        Where the secret comes from instead.
    """
    try:
        parts = urlsplit(url)
        has = bool(parts.username or parts.password or "@" in parts.netloc)
    except ValueError:
        has = "@" in url
    if has:
        raise ValueError(f"{where} {strip_userinfo(url)!r} must not carry credentials: {hint}")


def strip_userinfo(text: str) -> str:
    """``text`` with the ``user:password@`` of every URL in it replaced by ``***@``."""
    return _USERINFO.sub(r"\1***@", text)


def redact(text: str, secret: str | None) -> str:
    """``text`` with every form of ``secret`` (raw, percent-encoded, base64 as HTTP basic) replaced by ``***``.

    URLs' ``user:password@`` are blanked too, whatever the secret.
    """
    text = strip_userinfo(text)
    if not secret:
        return text
    forms = {secret, quote(secret, safe=""), quote(secret)}
    try:
        forms.add(base64.b64encode(secret.encode()).decode())
        forms.add(base64.b64encode(secret.encode()).decode().rstrip("="))
    except UnicodeEncodeError:
        pass
    for form in sorted((f for f in forms if len(f) >= 4 or f == secret), key=len, reverse=True):
        text = text.replace(form, "***")
    return text
