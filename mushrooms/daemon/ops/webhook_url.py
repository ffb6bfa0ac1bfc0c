"""The webhook's URL, checked once at start: a secret that is never shown, even when it is wrong.

A Slack incoming webhook holds its secret in the URL's path, so an error
about the URL must not quote it: :func:`parse_webhook_url` says *what* is
wrong (no ``https://``, no host, a bad IPv6 literal, a bad port, spaces,
``user:password@``) and *where* the URL came from (the systemd credential
``notify_url`` or ``$MUSHROOMS_NOTIFY_URL``), never the URL nor any part of
it.  ``mushrooms run`` and ``mushrooms rehearse`` check it before they touch
anything (:func:`checked_notify_url`): a URL that cannot be used is bad
input, one line and exit status 2 (the unit's ``RestartPreventExitStatus=2``
keeps systemd from looping on it).
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from typing import Any, Mapping
from urllib.parse import urlsplit

from ..credentials import CredentialsError, load_notify_url

__all__ = ["WebhookAddress", "WebhookURLError", "parse_webhook_url", "checked_notify_url", "notify_url_usable"]

_DEFAULT_PORT = {"https": 443, "http": 80}


class WebhookURLError(CredentialsError):
    """The webhook URL cannot be used; ``str()`` is one line that does not show it."""


@dataclass(frozen=True, repr=False)
class WebhookAddress:
    """Where a webhook's POSTs go, parsed once.

    Attributes
    ----------
    scheme : str
        ``https`` or ``http``.
    host : str
        A name or an IP address (an IPv6 one without its brackets).
    port : int
    host_header : str
        The ``Host:`` header (the URL's authority as written).
    target : str
        The request target: path and query (the secret of a Slack webhook).
    """

    scheme: str
    host: str
    port: int
    host_header: str
    target: str

    def __repr__(self) -> str:  # never the target, nor the host of a private webhook
        return f"WebhookAddress(scheme={self.scheme!r})"


def _problem(url: str) -> str | WebhookAddress:
    """What is wrong with ``url`` (words that do not quote it), or its address."""
    if not url.isascii() or any(ch.isspace() or not ch.isprintable() for ch in url):
        return "it contains spaces, control characters or characters outside ASCII (percent-encode them)"
    head = url.split(":", 1)[0].lower() if "://" in url else ""
    if head not in _DEFAULT_PORT:
        return "it does not start with https:// or http://"
    try:
        parts = urlsplit(url)
    except ValueError:  # "Invalid IPv6 URL": a bracket not closed
        return "its host is not a valid IPv6 literal in brackets"
    if "@" in parts.netloc:
        return "it must not carry user:password@ (a webhook's secret is its path)"
    host = parts.hostname
    if not host:
        return "it has no host"
    if parts.netloc.startswith("["):
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            return "its host is not a valid IPv6 literal in brackets"
    try:
        port = parts.port
    except ValueError:
        return "its port is not a number from 1 to 65535"
    port = _DEFAULT_PORT[head] if port is None else port
    if not 1 <= port <= 65535:
        return "its port is not a number from 1 to 65535"
    target = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
    return WebhookAddress(head, host, port, parts.netloc, target)


def parse_webhook_url(url: str, source: str = "the webhook setting") -> WebhookAddress:
    """The address of ``url``; :class:`WebhookURLError` (one line, never the URL) when it cannot be used.

    Parameters
    ----------
    url : str
        ``https://host[:port]/path[?query]`` (or ``http://``); IPv6 hosts in
        brackets.
    source : str
        Where it came from (``env:MUSHROOMS_NOTIFY_URL``, ``credential:notify_url``).
    """
    found = _problem(url.strip())
    if isinstance(found, str):
        raise WebhookURLError(f"the webhook URL from {source} cannot be used: {found} "
                              "(the URL is a secret and is not shown; fix it, or set [notify] target = \"off\")")
    return found


def checked_notify_url(environ: Mapping[str, str] | None = None) -> tuple[str, str, WebhookAddress]:
    """The URL of ``[notify]``, where it came from, and its address; raises :class:`CredentialsError` when unusable."""
    url, source = load_notify_url(environ)
    return url, source, parse_webhook_url(url, source)


def notify_url_usable(notify: Any, environ: Mapping[str, str] | None = None) -> None:
    """Refuse a start (:class:`CredentialsError`, one line) when ``[notify]`` is on and its URL is missing or unusable.

    Parameters
    ----------
    notify : NotifyConfig or None
        ``[notify]``; nothing is checked when it is off.
    environ : mapping, optional
        Environment (default ``os.environ``).
    """
    if notify is not None and notify.enabled:
        checked_notify_url(environ)
