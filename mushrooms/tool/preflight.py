"""``mushrooms preflight``: check the real installation end to end before an event, planning nothing.

One line per check, ``ok``, ``FAIL`` or ``skip`` and why (never a secret):

``config``       the config file loads and is valid (with ``--set``, ``--state``, ``--outbox``, ``--bootstrap``
                 as ``mushrooms run`` takes them);
``credentials``  the GCN client id and secret are found (systemd credentials, else the environment);
``kafka``        the installed Kafka clients keep GCN's token (the service's own check,
                 :func:`~mushrooms.daemon.kafka.versions.kafka_client_problem`: on GCN a failure before
                 anything is tried, on a local broker a warning); the configured broker answers with those
                 credentials (librdkafka itself: the OIDC token
                 fetch and the SASL login of gcn-kafka's settings, as the service's consumer) and lists
                 each ``[kafka] topics`` entry with its partitions (``AdminClient.list_topics``, nothing
                 consumed, no topic created);
``submission``   the ``[submit]`` target takes the token: a read-only GET (Kowalski: the queue list, ``GET
                 /api/triggers/ztf``; SkyPortal: the token's user, ``GET /api/internal/profile``, with the
                 permission to manage observation plans);
``submission_parts`` the ``[submit_parts]`` SkyPortal (issue 53: the other telescopes' parts) takes its token
                 (``skyportal_token``): the same read-only profile GET and permission, and the allocations named;
``webhook``      the ``[notify]`` URL is found and usable as the service checks it at start
                 (:mod:`~mushrooms.daemon.ops.webhook_url`); a test message only with ``--notify-test``;
``state``        (these three: :mod:`.preflight_paths`) the state file (``[daemon] state_path`` resolved as the service does) is a SQLite file of a
                 schema this program reads, or can be created; not a FIFO, directory or device; writable by
                 this user, not world-readable;
``directories``  the trigger and quarantine directories and the pid file's directory exist or can be created,
                 writable by this user;
``outbox``       the directory sink's directory (or the Kafka sink's broker) is usable.

Exit status 0 when every check is ``ok`` or ``skip``, 1 when one failed, 2 for bad usage.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any, Callable, Sequence

from .common import add_common_options, execute, tool_parser
from .preflight_paths import directories_check, outbox_directory_check, state_check
from .settings_flag import add_set_option

__all__ = ["HELP", "parser", "run", "main", "kafka_check", "Result"]

HELP = "check the installation before an event (GCN credentials and topic, submission token, webhook, paths)"

#: (status, name, reason); status is ``ok``, ``FAIL`` or ``skip``.
Result = tuple[str, str, str]

#: Characters of a reason printed (a server's text can be long).
REASON_CHARS = 400


def _timeout(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and 0.5 <= value <= 600):
        raise argparse.ArgumentTypeError(f"must be a number of seconds in [0.5, 600], got {text!r}")
    return value


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms preflight`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("preflight", HELP)
    p.add_argument("--notify-test", action="store_true",
                   help="post one test message to the [notify] webhook (default: only check its URL)")
    p.add_argument("--timeout", type=_timeout, default=15.0, metavar="S",
                   help="wait at most S seconds for each network check (default 15)")
    p.add_argument("--bootstrap", metavar="HOST:PORT", help="local plaintext broker, no credentials (as run)")
    p.add_argument("--outbox", metavar="DIR", help="directory sink (as run)")
    p.add_argument("--state", metavar="FILE", help="SQLite state file (as run)")
    add_set_option(p)
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms preflight`` on its own."""
    return execute("preflight", parser().parse_args(args), run)


def _clean(text: object) -> str:
    from ..handlers.text import storable

    return storable(text, REASON_CHARS)


def run(args: argparse.Namespace) -> int:
    """Run every check, print one line each; 0 when none failed, else 1."""
    results: list[Result] = []

    def say(result: Result) -> None:
        status, name, reason = result
        results.append(result)
        print(f"{status:<4} {name}: {_clean(reason)}", flush=True)

    config = _config_check(args, say)
    checks: tuple[tuple[str, Callable[[Any], Result]], ...] = (
        ("credentials", _credentials_check),
        ("kafka", lambda c: kafka_check(c.kafka, args.timeout)),
        ("submission", lambda c: _submission_check(c.submit, args.timeout)),
        ("submission_parts", lambda c: _parts_check(c.submit_parts, args.timeout)),
        ("webhook", lambda c: _webhook_check(c.notify, args.notify_test)),
        ("state", state_check),
        ("directories", directories_check),
        ("outbox", lambda c: _outbox_check(c.outbound, args.timeout)),
    )
    for name, check in checks:
        if config is None:
            say(("skip", name, "the configuration did not load"))
            continue
        try:
            say(check(config))
        except Exception as exc:  # a check that breaks is a failed check, in one line
            say(("FAIL", name, f"internal error: {type(exc).__name__}: {exc}"))
    failed = [name for status, name, _ in results if status == "FAIL"]
    print(f"preflight: {len(failed)} check(s) failed ({', '.join(failed)})" if failed else
          f"preflight: all {len(results)} checks ok or skipped", flush=True)
    return 1 if failed else 0


def _config_check(args: argparse.Namespace, say: Callable[[Result], None]) -> Any:
    from .config import ConfigError
    from .overrides import effective_config
    from .settings_flag import parse_set

    for text in getattr(args, "set", None) or ():
        try:
            parse_set(text)
        except ValueError as exc:  # a malformed --set is bad usage (exit 2), not a failed check
            raise ConfigError(str(exc)) from None
    try:
        config = effective_config(args)
    except ConfigError as exc:
        say(("FAIL", "config", str(exc)))
        return None
    why = "" if getattr(args, "config", None) else " (no config file: the embedded defaults)"
    say(("ok", "config", f"{config.source}: valid{why}"))
    return config


# ---------------------------------------------------------------- GCN Kafka
def _credentials_check(config: Any) -> Result:
    from ..daemon.credentials import CredentialsError, load_credentials

    if config.kafka.bootstrap:
        return "skip", "credentials", f"local broker {config.kafka.bootstrap} in plaintext: no credentials used"
    try:
        creds = load_credentials()
    except CredentialsError as exc:
        return "FAIL", "credentials", str(exc)
    return "ok", "credentials", f"GCN client id {creds.client_id} and its secret, from {creds.source}"


def kafka_check(kafka: Any, timeout_s: float, credentials: Any = None, extra: dict[str, Any] | None = None) -> Result:
    """Connect to the configured broker as the service's consumer would and list the topics' partitions.

    Parameters
    ----------
    kafka : KafkaConfig
        ``[kafka]``: ``bootstrap`` (a local plaintext broker) or ``domain`` (GCN, OIDC credentials).
    timeout_s : float
        How long (s) to wait for the broker's metadata.
    credentials : Credentials, optional
        GCN client id and secret (default: :func:`~mushrooms.daemon.credentials.load_credentials`).
    extra : dict, optional
        librdkafka settings laid over gcn-kafka's (tests: a token endpoint and a broker on loopback).
    """
    import gcn_kafka

    from ..daemon.credentials import CredentialsError, load_credentials
    from ..daemon.kafka import versions

    conf: dict[str, Any] = {"client.id": "mushrooms-preflight", "allow.auto.create.topics": False}
    secret = None
    too_old = versions.kafka_client_problem()  # what the service refuses to start with on GCN (warns on a local one)
    if kafka.bootstrap and credentials is None:
        conf.update({"bootstrap.servers": kafka.bootstrap, "security.protocol": "plaintext"})
        where, login = kafka.bootstrap, {}
    elif too_old is not None:
        return "FAIL", "kafka", f"not tried: {too_old}"
    else:
        try:
            creds = credentials or load_credentials()
        except CredentialsError:
            return "FAIL", "kafka", "not tried: no GCN credentials (see credentials)"
        secret = creds.client_secret
        where = f"kafka.{kafka.domain}"
        login = {"client_id": creds.client_id, "client_secret": creds.client_secret, "domain": kafka.domain}
    conf.update(extra or {})
    where = conf.get("bootstrap.servers", where)
    errors: list[Any] = []
    conf.update({"error_cb": errors.append, "logger": _quiet_logger()})
    admin = gcn_kafka.AdminClient(config=conf, **login)
    started = time.monotonic()
    md, why = _metadata(admin, errors, timeout_s)
    if md is None:
        return "FAIL", "kafka", _redact(f"{where}: {why}", secret)
    took = time.monotonic() - started
    found, parts = [], []
    for topic in kafka.topics:
        t = admin.list_topics(topic, timeout=max(1.0, timeout_s - took)).topics.get(topic)
        if t is None or t.error is not None or not t.partitions:
            err = "no partitions" if t is None or t.error is None else t.error.str()
            return "FAIL", "kafka", _redact(f"{where} answered in {took:.1f} s, but topic {topic}: {err} "
                                            "(the topic's name, or the credentials' access to it)", secret)
        parts += [(topic, p) for p in sorted(t.partitions)]
        leaderless = sorted(p for p, pm in t.partitions.items() if pm.leader < 0 or pm.error is not None)
        found.append(f"{topic}: {len(t.partitions)} partition(s)"
                     + (f", WITHOUT a leader: {leaderless}" if leaderless else ""))
        if leaderless:
            return "FAIL", "kafka", f"{where}: " + "; ".join(found)
    group_ok, group = _group_offsets(admin, getattr(kafka, "group_id", None), parts, timeout_s)
    if group:
        found.append(group)
    if not group_ok:
        return "FAIL", "kafka", _redact(f"{where}: " + "; ".join(found), secret)
    auth = "" if not login else f" as {login['client_id']} (OIDC token and SASL login accepted)"
    if too_old is not None:  # a local broker needs no token: as the service, a warning
        found.append(f"warning (a local broker needs no token): {too_old}")
    return "ok", "kafka", f"{where} answered in {took:.1f} s{auth}" + "".join(f"; {f}" for f in found)


def _group_offsets(admin: Any, group: str | None, parts: list[tuple[str, int]], timeout_s: float) -> tuple[bool, str]:
    """(readable, what the consumer group has committed on ``parts``): the group must be readable with the credentials."""
    from confluent_kafka import ConsumerGroupTopicPartitions, KafkaException, TopicPartition

    if not group or not parts:
        return True, ""
    request = [ConsumerGroupTopicPartitions(group, [TopicPartition(t, p) for t, p in parts])]
    try:
        (future,) = admin.list_consumer_group_offsets(request, request_timeout=timeout_s).values()
        answer = future.result(timeout=timeout_s + 5)
    except (KafkaException, TimeoutError) as exc:
        why = exc.args[0].str() if exc.args and hasattr(exc.args[0], "str") else str(exc) or type(exc).__name__
        return False, f"group {group}: its committed offsets cannot be read: {why}"
    bad = [tp for tp in answer.topic_partitions if tp.error is not None]
    if bad:
        return False, f"group {group}: {bad[0].topic}[{bad[0].partition}]: {bad[0].error.str()}"
    done = [tp for tp in answer.topic_partitions if tp.offset >= 0]
    return True, (f"group {group}: committed offsets on {len(done)} of {len(parts)} partition(s)"
                  + (" (the others start where [kafka] offset_reset says)" if len(done) < len(parts) else ""))


def _metadata(admin: Any, errors: list[Any], timeout_s: float) -> tuple[Any, str]:
    """The cluster's metadata within ``timeout_s``, or (None, why): refused credentials end the wait at once."""
    from confluent_kafka import KafkaError, KafkaException

    refused = {KafkaError._AUTHENTICATION, KafkaError.SASL_AUTHENTICATION_FAILED,
               KafkaError.CLUSTER_AUTHORIZATION_FAILED, KafkaError.TOPIC_AUTHORIZATION_FAILED}
    deadline = time.monotonic() + timeout_s
    last = "no answer"
    while True:
        left = deadline - time.monotonic()
        try:
            return admin.list_topics(timeout=max(0.1, min(1.0, left))), ""
        except KafkaException as exc:
            last = exc.args[0].str() if exc.args and hasattr(exc.args[0], "str") else str(exc)
        admin.poll(0)  # serves error_cb
        auth = [e for e in errors if hasattr(e, "code") and e.code() in refused]
        if auth:
            return None, _refusal(auth[0].str())
        if left <= 0:
            told = [e.str() for e in errors if hasattr(e, "code") and e.code() != KafkaError._ALL_BROKERS_DOWN]
            return None, f"no answer within {timeout_s:g} s: {told[-1] if told else last}"


#: What curl says when the token endpoint did not answer (librdkafka's ``rdhttp.c`` passes curl's text on;
#: an HTTP error passes the endpoint's body on instead).
_NO_ANSWER = ("resolve", "connect", "timed out", "timeout", "ssl", "certificate", "empty reply", "recv failure",
              "send failure", "terminating", "not json encoded", "failed to parse json")
_TOKEN = "Failed to acquire SASL OAUTHBEARER token:"


def _refusal(text: str) -> str:
    """Who refused, in words: the OIDC token endpoint (credentials), the token endpoint unreachable, or the broker."""
    if _TOKEN in text:
        said = text.split(_TOKEN, 1)[1].strip()
        if any(k in said.lower() for k in _NO_ANSWER):
            return f"the OIDC token endpoint gave no token (not a refusal of the credentials): {said}"
        return f"credentials refused by the OIDC token endpoint: {said}"
    return f"credentials refused by the broker (SASL): {text}"


def _quiet_logger() -> Any:
    """librdkafka's own lines: to ``mushrooms.kafka.librdkafka`` when debugging, else nowhere."""
    import logging

    from ..daemon.kafka.broker_log import kafka_logger

    if logging.getLogger().isEnabledFor(logging.DEBUG):
        return kafka_logger()
    quiet = logging.getLogger("mushrooms.preflight.librdkafka")
    quiet.propagate = False
    if not quiet.handlers:
        quiet.addHandler(logging.NullHandler())
    return quiet


def _redact(text: str, secret: str | None) -> str:
    from ..handlers.secret_text import redact

    return redact(text, secret)


# ---------------------------------------------------------------- submission and webhook
def _parts_check(parts: Any, timeout_s: float) -> Result:
    """``[submit_parts]``: its SkyPortal takes its token, whose user may manage observation plans."""
    from types import SimpleNamespace

    from ..daemon.credentials import load_parts_token

    if not parts.enabled:
        return "skip", "submission_parts", "[submit_parts] enabled = false: the SkyPortal parts are written, not sent"
    if parts.dry_run:
        return "skip", "submission_parts", "[submit_parts] dry_run = true: the requests are logged, not sent"
    shim = SimpleNamespace(enabled=True, dry_run=False, target="skyportal", url=parts.url, timeout_s=parts.timeout_s)
    status, _, reason = _submission_check(shim, timeout_s, load_parts_token)
    listed = ", ".join(f"{k} {v}" for k, v in sorted(parts.allocations.items())) or "none: nothing will be sent"
    return status, "submission_parts", f"{reason}; allocations: {listed}"


def _submission_check(submit: Any, timeout_s: float, load: Any = None) -> Result:
    from ..daemon.credentials import CredentialsError, load_submit_token
    from ..daemon.submission.remote import KOWALSKI_PATH, Request, Unreachable, make_client

    if not submit.enabled:
        return "skip", "submission", '[submit] target = "none": plans are not submitted'
    if submit.dry_run:
        return "skip", "submission", f"[submit] dry_run = true: requests to {submit.target} are logged, not sent"
    try:
        token, source = (load or load_submit_token)()
    except CredentialsError as exc:
        return "FAIL", "submission", str(exc)
    client = make_client(submit.target, submit.url, token, min(timeout_s, submit.timeout_s * 3))
    path = KOWALSKI_PATH if submit.target == "kowalski" else "/api/internal/profile"
    where = f"{submit.target} at {client.base}, token from {source}"
    try:
        answer = client.send(Request("GET", client.base + path, None, client.auth_scheme))
    except Unreachable as exc:
        return "FAIL", "submission", f"{where}: unreachable: {exc}"
    said = f"GET {path} answered {answer.status}: {answer.message()}"
    if answer.status in (400, 401, 403):
        return "FAIL", "submission", f"{where}: token refused ({said})"
    data = answer.data.get("data") if isinstance(answer.data, dict) else None
    if submit.target == "kowalski":
        if answer.ok and isinstance(data, list):
            return "ok", "submission", f"{where}: token accepted (GET {path}: {len(data)} queue(s) listed)"
        return "FAIL", "submission", f"{where}: not the queue list Kowalski answers ({said})"
    if not (answer.ok and isinstance(data, dict)):
        return "FAIL", "submission", f"{where}: not the profile SkyPortal answers ({said})"
    perms = data.get("permissions") if isinstance(data.get("permissions"), list) else []
    user = data.get("username", "?")
    if not {"Manage observation plans", "System admin"} & set(map(str, perms)):
        return "FAIL", "submission", (f"{where}: token accepted (user {user}), but the user lacks the "
                                      "permission 'Manage observation plans' that posting a plan needs")
    return "ok", "submission", f"{where}: token accepted (user {user}, may manage observation plans)"


def _webhook_check(notify: Any, send_test: bool) -> Result:
    from ..daemon.credentials import CredentialsError
    from ..daemon.ops.webhook_url import checked_notify_url

    if not notify.enabled:
        return "skip", "webhook", '[notify] target = "off": no notifications'
    try:  # found, then checked as the service checks it at start (never shown), before any test message
        url, source, address = checked_notify_url()
    except CredentialsError as exc:
        return "FAIL", "webhook", str(exc)
    where = f"{notify.target} webhook, {address.scheme} URL at host {address.host}, from {source}"
    if not send_test:
        return "ok", "webhook", f"{where}; no message sent (--notify-test sends one)"
    sent, why = _post_test(url, notify)
    if sent:
        return "ok", "webhook", f"{where}; test message accepted ({why})"
    return "FAIL", "webhook", f"{where}; test message not accepted: {why}"


def _post_test(url: str, notify: Any) -> tuple[bool, str]:
    """Post one test message the way the service posts its messages; (accepted, what the sender logged)."""
    import logging
    import socket

    from ..daemon.ops.webhook import Webhook

    said: list[str] = []

    class _Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            said.append(record.getMessage())

    hook_log = logging.getLogger("mushrooms.daemon.webhook")
    keep = _Keep()
    hook_log.addHandler(keep)
    hook = None
    try:
        hook = Webhook(url, notify.target, timeout_s=notify.timeout_s, max_pending=1)
        hook.post("preflight_test", f"mushrooms preflight on {socket.gethostname()}: test message, nothing "
                                    "happened (sent by mushrooms preflight --notify-test)")
        hook.close(timeout_s=notify.timeout_s + 2.0)
    finally:
        hook_log.removeHandler(keep)
    last = said[-1] if said else "no answer before the deadline"
    return (getattr(hook, "sent", 0) >= 1 and not getattr(hook, "failed", 0)), _redact(last, url)


def _outbox_check(outbound: Any, timeout_s: float) -> Result:
    if outbound.sink == "kafka":
        from ..daemon.credentials import CredentialsError
        from ..daemon.kafka.sink import sink_security

        try:
            security, described = sink_security(outbound)
        except CredentialsError as exc:
            return "FAIL", "outbox", str(exc)
        probe = type("_Outbound", (), {"bootstrap": outbound.bootstrap, "topics": ()})()
        status, _, reason = kafka_check(probe, timeout_s, extra=security)
        return status, "outbox", f"Kafka sink, topic {outbound.topic}, {described}: {reason}"
    return outbox_directory_check(outbound)


if __name__ == "__main__":
    sys.exit(main())
