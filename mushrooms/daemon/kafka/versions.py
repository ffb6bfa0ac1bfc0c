"""The Kafka client versions that keep a GCN session alive, checked when the service starts.

gcn-kafka before 0.3.4 refreshed the GCN OAuth token in Python (an ``oauth_cb`` built on
authlib), which librdkafka only calls from ``poll``/``consume``; GCN's brokers end a session when
its token expires (about an hour), and such clients then fail with
``SASL authentication error: {"status":"invalid_token"}`` and receive nothing more until
restarted (nasa-gcn/gcn-kafka-python issue 49).  gcn-kafka 0.3.4 hands the OpenID Connect flow
to librdkafka itself (``sasl.oauthbearer.method=oidc``, refreshed in its own thread) and sets
``https.ca.location`` for the token endpoint, a property librdkafka gained in 2.11.0 (the CA
certificates of the statically linked OpenSSL in the wheels); hence confluent-kafka >= 2.11.
An older pair is refused at start with one line (GCN) or warned about (a local broker).
"""

from __future__ import annotations

import importlib.metadata
import logging
import re
from typing import Callable

from ...scheduler_core.errors import InputError

__all__ = ["MIN_GCN_KAFKA", "MIN_CONFLUENT_KAFKA", "KafkaClientTooOld", "kafka_client_problem",
           "require_kafka_clients", "check_kafka_clients"]

MIN_GCN_KAFKA = (0, 3, 4)
MIN_CONFLUENT_KAFKA = (2, 11, 0)


class KafkaClientTooOld(InputError):
    """gcn-kafka, confluent-kafka or librdkafka is older than what keeps the GCN token; one line."""


def _release(text: str) -> tuple[int, ...] | None:
    m = re.match(r"\s*(\d+)\.(\d+)(?:\.(\d+))?", text or "")
    return None if m is None else tuple(int(x or 0) for x in m.groups())


def _shown(v: tuple[int, ...]) -> str:
    return ".".join(map(str, v))


def _librdkafka() -> str:
    import confluent_kafka

    return str(confluent_kafka.libversion()[0])


def kafka_client_problem(version: Callable[[str], str] = importlib.metadata.version,
                         librdkafka: Callable[[], str] = _librdkafka) -> str | None:
    """What is too old among gcn-kafka, confluent-kafka and the librdkafka it runs on; None when all fit.

    Parameters
    ----------
    version : callable
        Installed version of a distribution (default :func:`importlib.metadata.version`).
    librdkafka : callable
        Version of the librdkafka confluent-kafka is linked with (a source build may use
        the system's).

    Returns
    -------
    str or None
        One line naming what is installed, what is needed and why.
    """
    found = []
    for dist, need in (("gcn-kafka", MIN_GCN_KAFKA), ("confluent-kafka", MIN_CONFLUENT_KAFKA)):
        try:
            have = version(dist)
        except importlib.metadata.PackageNotFoundError:
            have = "none"
        rel = _release(have)
        if rel is None or rel < need:
            found.append(f"{dist} {have} (needs >= {_shown(need)})")
    lib = librdkafka()
    rel = _release(lib)
    if rel is None or rel < MIN_CONFLUENT_KAFKA:
        found.append(f"librdkafka {lib} (needs >= {_shown(MIN_CONFLUENT_KAFKA)})")
    if not found:
        return None
    return (f"{', '.join(found)} installed: older Kafka clients lose the GCN token after about an hour "
            f"(SASL authentication error invalid_token) and receive no alert until restarted; install "
            f"'gcn-kafka>={_shown(MIN_GCN_KAFKA)}' 'confluent-kafka>={_shown(MIN_CONFLUENT_KAFKA)}'")


def require_kafka_clients() -> None:
    """Raise :class:`KafkaClientTooOld` (one line) when the clients would lose GCN's token."""
    problem = kafka_client_problem()
    if problem is not None:
        raise KafkaClientTooOld(problem)


def check_kafka_clients(gcn: bool) -> None:
    """At start: refuse (GCN, ``gcn`` True) or warn (a local broker, which needs no token) on old clients."""
    if gcn:
        require_kafka_clients()
        return
    problem = kafka_client_problem()
    if problem is not None:
        logging.getLogger("mushrooms.daemon").warning("event=kafka_clients_too_old local broker only: %s", problem)
