"""The configured source of executed observations: ``[loop] executed_source``, parsed (standard library only).

``"none" | "file:PATH" | "depot:URL_OR_DIR" | "skyportal:URL"``: a light
leaf, so reading the configuration (``mushrooms.tool.config``) validates the
setting without importing the readers' numpy and astropy
(:mod:`.executed` re-exports these names).
"""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import urlparse

from .secret_text import refuse_url_credentials

__all__ = ["ExecutedSource", "SOURCE_KINDS", "parse_executed_source"]

#: The kinds of ``executed_source`` a configuration may name.
SOURCE_KINDS = ("none", "file", "depot", "skyportal")


@dataclass(frozen=True)
class ExecutedSource:
    """Where executed observations come from.

    Attributes
    ----------
    kind : str
        ``none``, ``file`` (a JSON-lines file), ``depot`` (ZTF's depot: a
        URL or a directory holding ``<YYYYMMDD>/ztf_recentproc_<YYYYMMDD>.json``)
        or ``skyportal`` (a SkyPortal base URL).
    location : str or None
        The path or URL; None for ``none``.
    """

    kind: str
    location: str | None = None


def parse_executed_source(spec: str) -> ExecutedSource:
    """The configuration's ``"none" | "file:PATH" | "depot:URL_OR_DIR" | "skyportal:URL"``.

    Parameters
    ----------
    spec : str
        The setting (surrounding blanks ignored).

    Returns
    -------
    ExecutedSource

    Raises
    ------
    ValueError
        One line saying what is wrong and what is accepted.
    """
    forms = '"none", "file:PATH", "depot:URL_OR_DIR" or "skyportal:URL"'
    if not isinstance(spec, str):
        raise ValueError(f"executed source {spec!r}: a {type(spec).__name__}, not a string; give {forms}")
    text = spec.strip()
    if text == "none":
        return ExecutedSource("none")
    kind, sep, location = text.partition(":")
    if not sep or kind not in SOURCE_KINDS or kind == "none":
        raise ValueError(f"executed source {spec!r}: unknown kind {kind!r}; give {forms}")
    location = location.strip()
    if not location:
        raise ValueError(f"executed source {spec!r}: no location after '{kind}:'; give {forms}")
    url = urlparse(location)
    is_url = url.scheme in ("http", "https")
    if kind == "skyportal" and not (is_url and url.netloc):
        raise ValueError(f"executed source {spec!r}: SkyPortal needs an http(s) URL with a host "
                         "(skyportal:https://fritz.science)")
    if kind == "depot" and url.scheme and not is_url and len(url.scheme) > 1:  # "C:\..." is a path
        raise ValueError(f"executed source {spec!r}: a depot is an http(s) URL or a directory, not {url.scheme}:")
    if kind == "depot" and is_url and not url.netloc:
        raise ValueError(f"executed source {spec!r}: the depot URL has no host")
    if is_url:  # (L1) the token comes from the credential, never from the URL (nor into logs and the state)
        refuse_url_credentials(location, f"executed source {kind}:", "the token comes from "
                               "MUSHROOMS_EXECUTED_TOKEN or the systemd credential executed_token")
    if kind == "file" and is_url:
        raise ValueError(f"executed source {spec!r}: file: takes a path, not a URL")
    return ExecutedSource(kind, location)
