"""Checks shared by the settings of every HTTP sender (``[submit]``, ``[submit_parts]``).

One place for the rules both tables state alike: a base URL is ``http(s)``
with a host and no credentials in it (the token comes from the environment
or a systemd credential), every time is a finite number of seconds within
its range, and the back-off does not shrink.
"""

from __future__ import annotations

import math
from typing import Any, Iterable
from urllib.parse import urlsplit

from ...handlers.secret_text import refuse_url_credentials

__all__ = ["check_base_url", "check_seconds"]


def check_base_url(url: str, section: str, when: str, token_from: str) -> None:
    """Refuse a base URL that is not ``http(s)://host...`` or that carries credentials.

    Parameters
    ----------
    url : str
        The configured base URL.
    section : str
        The table, e.g. ``"[submit]"`` (named in the message).
    when : str
        When the URL is required, e.g. ``"when enabled"`` (named in the message).
    token_from : str
        Where the token comes from instead (the message of a URL with credentials).

    Raises
    ------
    ValueError
        One line; a URL with credentials is never shown.
    """
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.netloc:
        raise ValueError(f"{section} url must be an http(s) URL {when}, got {url!r}")
    refuse_url_credentials(url, f"{section} url", f"the token comes from {token_from}")


def check_seconds(config: Any, section: str, limits: Iterable[tuple[str, float, float]]) -> None:
    """Refuse a time (s) that is not finite within its range, or a back-off whose maximum is below its start.

    Parameters
    ----------
    config : dataclass instance
        Has the named attributes (and ``retry_initial_s``, ``retry_max_s``).
    section : str
        The table, e.g. ``"[submit]"``.
    limits : iterable of (str, float, float)
        Attribute name, least and greatest value (s).

    Raises
    ------
    ValueError
        One line naming the key.
    """
    for name, low, high in limits:
        value = float(getattr(config, name))
        if not (math.isfinite(value) and low <= value <= high):
            raise ValueError(f"{section} {name} must be a finite number in [{low:g}, {high:g}] s, got {value!r}")
    if config.retry_max_s < config.retry_initial_s:
        raise ValueError(f"{section} retry_max_s must be >= retry_initial_s")
