"""Kafka credentials: from the environment or systemd credentials.

Never from ``config.toml``.  GCN client id and secret, first match wins:

1. ``$CREDENTIALS_DIRECTORY/gcn_client_id`` and ``.../gcn_client_secret``
   (systemd ``LoadCredential=``/``LoadCredentialEncrypted=``);
2. ``$GCN_CLIENT_ID`` and ``$GCN_CLIENT_SECRET``.

Id and secret may come from different places (the id is not secret and may
sit in an ``Environment=`` line while the secret is a credential).

The outbound Kafka sink's SASL password (when ``[outbound] security_protocol``
is ``sasl_*``): ``$CREDENTIALS_DIRECTORY/outbound_password``, else
``$MUSHROOMS_OUTBOUND_PASSWORD``.

The bearer token of ``[submit]`` (Kowalski or SkyPortal):
``$CREDENTIALS_DIRECTORY/submit_token``, else ``$MUSHROOMS_SUBMIT_TOKEN``.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

__all__ = ["Credentials", "CredentialsError", "load_credentials", "load_outbound_password", "load_submit_token", "load_notify_url",
           "load_executed_token", "load_parts_token", "service_tokens"]

#: the service's log (where each token came from)
log = logging.getLogger("mushrooms.daemon")


class CredentialsError(ValueError):
    """A credential (GCN client id/secret, outbound password, submission token) is missing or unreadable.

    Bad input, like a bad config file: the tools answer it with one line and
    exit status 2 (``mushrooms.tool.common.execute``).
    """


@dataclass(frozen=True)
class Credentials:
    """GCN OIDC client credentials."""

    client_id: str
    client_secret: str
    source: str

    def __repr__(self) -> str:  # never print the secret
        return f"Credentials(client_id={self.client_id!r}, client_secret='***', source={self.source!r})"


def _read_credential(name: str, env: Mapping[str, str]) -> str | None:
    directory = env.get("CREDENTIALS_DIRECTORY")
    if not directory:
        return None
    path = Path(directory) / name
    try:
        value = path.read_text().strip()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise CredentialsError(f"cannot read systemd credential {path}: {exc.strerror or exc}") from None
    return value or None


def _lookup(credential: str, variable: str, env: Mapping[str, str]) -> tuple[str | None, str | None]:
    """One secret: the systemd credential ``credential``, else ``$variable``.

    Returns the value and where it came from (``credential:NAME`` or
    ``env:NAME``), or ``(None, None)``.
    """
    value = _read_credential(credential, env)
    if value:
        return value, f"credential:{credential}"
    value = env.get(variable, "").strip()
    if value:
        return value, f"env:{variable}"
    return None, None


def load_credentials(environ: Mapping[str, str] | None = None) -> Credentials:
    """Find the GCN client id and secret.

    Parameters
    ----------
    environ : mapping, optional
        Environment (default ``os.environ``).

    Raises
    ------
    CredentialsError
        With a one-line hint when either value is missing.
    """
    env = os.environ if environ is None else environ
    client_id, id_source = _lookup("gcn_client_id", "GCN_CLIENT_ID", env)
    secret, secret_source = _lookup("gcn_client_secret", "GCN_CLIENT_SECRET", env)
    if not client_id or not secret:
        missing = [n for n, v in (("client id", client_id), ("client secret", secret)) if not v]
        raise CredentialsError(
            f"GCN {' and '.join(missing)} not found: set GCN_CLIENT_ID/GCN_CLIENT_SECRET or "
            "systemd credentials gcn_client_id/gcn_client_secret "
            "(or use --bootstrap HOST:PORT for a local broker)"
        )
    return Credentials(client_id=client_id, client_secret=secret, source=f"{id_source}, {secret_source}")


def _secret(credential: str, variable: str, missing: str, environ: Mapping[str, str] | None) -> tuple[str, str]:
    """One secret and where it came from (systemd credential first, then the variable), or ``CredentialsError(missing)``.

    A secret that cannot go into an HTTP header or a SASL field as it is
    (a line break or another control character inside it, or a character
    outside Latin-1) is refused here, with one line that names where it came
    from and never shows it: sent, it would be refused on every retry and its
    text would reach the journal in the error.
    """
    env = os.environ if environ is None else environ
    value, source = _lookup(credential, variable, env)
    if value and source:
        bad = next((what for what, test in (
            ("a line break", lambda ch: ch in "\r\n"),
            ("a control character", lambda ch: ord(ch) < 32 or ord(ch) == 127),
            ("a character outside Latin-1", lambda ch: ord(ch) > 255)) if any(map(test, value))), None)
        if bad:
            raise CredentialsError(f"the secret from {source} ({len(value)} characters) contains {bad}: refused "
                                   "(write it on one line, without quotes or other characters around it)")
        return value, source
    raise CredentialsError(missing)


def load_outbound_password(environ: Mapping[str, str] | None = None) -> tuple[str, str]:
    """Find the SASL password of the outbound Kafka sink.

    Parameters
    ----------
    environ : mapping, optional
        Environment (default ``os.environ``).

    Returns
    -------
    password, source : str
        The password and where it came from (for logs; never the value).

    Raises
    ------
    CredentialsError
        With a one-line hint when it is missing.
    """
    return _secret("outbound_password", "MUSHROOMS_OUTBOUND_PASSWORD",
                   "outbound Kafka SASL password not found: set MUSHROOMS_OUTBOUND_PASSWORD or the systemd "
                   "credential outbound_password (or set [outbound] security_protocol to plaintext/ssl)", environ)


def load_submit_token(environ: Mapping[str, str] | None = None) -> tuple[str, str]:
    """Find the bearer token of the submission target (Kowalski or SkyPortal).

    The systemd credential ``submit_token`` first, else ``$MUSHROOMS_SUBMIT_TOKEN``
    (:func:`_token`: never from ``config.toml``, never logged nor stored).
    """
    return _token("submit_token", "MUSHROOMS_SUBMIT_TOKEN", "submission token",
                  "or set [submit] target = \"none\" or dry_run = true", environ)


def load_parts_token(environ: Mapping[str, str] | None = None) -> tuple[str, str]:
    """Find the SkyPortal token of ``[submit_parts]`` (the other telescopes' observation plans).

    The systemd credential ``skyportal_token`` first, else ``$MUSHROOMS_SKYPORTAL_TOKEN``
    (:func:`_token`: never from ``config.toml``, never logged nor stored).
    """
    return _token("skyportal_token", "MUSHROOMS_SKYPORTAL_TOKEN", "SkyPortal token of [submit_parts]",
                  "or set [submit_parts] enabled = false or dry_run = true", environ)


def load_executed_token(environ: Mapping[str, str] | None = None) -> tuple[str, str]:
    """Find the token of a URL source of executed observations (``[loop] executed_source``).

    The systemd credential ``executed_token`` first, else ``$MUSHROOMS_EXECUTED_TOKEN``
    (:func:`_token`).  SkyPortal takes it as ``Authorization: token <token>``;
    ZTF's depot as HTTP basic auth, the token being ``USER:PASSWORD``.
    """
    return _token("executed_token", "MUSHROOMS_EXECUTED_TOKEN", "executed-observations token",
                  "or use a file: or depot:DIR source in [loop] executed_source", environ)


def _token(credential: str, variable: str, what: str, otherwise: str,
           environ: Mapping[str, str] | None) -> tuple[str, str]:
    """A service token: the systemd credential ``credential`` (``$CREDENTIALS_DIRECTORY/<credential>``), else ``$variable``.

    Never from ``config.toml``; the value is never logged nor stored.

    Returns
    -------
    token, source : str
        The token and where it came from (for logs; never the value).

    Raises
    ------
    CredentialsError
        With a one-line hint when it is missing.
    """
    return _secret(credential, variable,
                   f"{what} not found: set {variable} or the systemd credential {credential} ({otherwise})", environ)


def load_notify_url(environ: Mapping[str, str] | None = None) -> tuple[str, str]:
    """Find the webhook URL of ``[notify]`` (a Slack incoming webhook holds its secret in the URL).

    The systemd credential ``notify_url`` first, else ``$MUSHROOMS_NOTIFY_URL``
    (:func:`_token`: never from ``config.toml``, never logged nor stored).
    """
    return _token("notify_url", "MUSHROOMS_NOTIFY_URL", "webhook URL", "or set [notify] target = \"off\"", environ)


def service_tokens(config: Any) -> tuple[str | None, str | None]:
    """The secrets ``mushrooms run`` needs, read before it touches any state (a missing one fails the start fast).

    The Kafka clients' versions are checked first (on GCN an older pair,
    which would lose its token after an hour, raises
    :class:`~.kafka.versions.KafkaClientTooOld`; on a local broker it is a
    warning).  Kafka's client id and secret are checked (the consumer reads them again);
    the submission token when ``[submit]`` sends for real; the token of an
    executed-observation source that is a URL.  Only where each came from is
    logged, never a value.

    Parameters
    ----------
    config : ServiceConfig
        The assembled sections (``kafka``, ``submit``, ``loop``).

    Returns
    -------
    submit_token, executed_token : str or None

    Raises
    ------
    CredentialsError
        A credential the configuration needs is missing or unreadable.
    """
    from .kafka.versions import check_kafka_clients

    check_kafka_clients(gcn=not config.kafka.bootstrap)  # clients that keep GCN's token: else one line (GCN)
    if not config.kafka.bootstrap:
        load_credentials()
    submit_token = None
    if config.submit.enabled and not config.submit.dry_run:
        submit_token, source = load_submit_token()
        log.info("event=submit_token source=%s", source)
    executed_token = None
    loop = getattr(config, "loop", None)
    if loop is not None and loop.enabled and str(loop.source.location).startswith(("http://", "https://")):
        executed_token, source = load_executed_token()  # the value is never logged
        log.info("event=executed_token source=%s", source)
    return submit_token, executed_token
