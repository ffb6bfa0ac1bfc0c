"""Outbound Kafka topic: the Kafka implementation of the ``Sink`` protocol.

One JSON message per plan or withdrawal, keyed by superevent id so that all
messages of one event stay in order on one partition.  The producer is
idempotent with ``acks=all``; :meth:`KafkaSink.publish` returns only once the
broker has acknowledged the message and raises otherwise, so the outbox row
stays pending and is retried.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any, Mapping

import confluent_kafka

from ..credentials import CredentialsError, load_outbound_password
from .broker_log import BrokerHealth, client_settings, kafka_logger
from ...scheduler_core.plan import strict_json
from ..settings import OutboundConfig
from ..sinks import SinkError

__all__ = ["KafkaSink", "PublishError", "sink_security"]

log = logging.getLogger("mushrooms.daemon.kafka_sink")


class PublishError(SinkError):
    """The broker did not acknowledge a message in time."""


def sink_security(config: OutboundConfig, environ: Mapping[str, str] | None = None) -> tuple[dict[str, str], str]:
    """librdkafka security settings of the outbound producer.

    Parameters
    ----------
    config : OutboundConfig
        Uses ``security_protocol``, ``sasl_mechanism``, ``sasl_username``.
    environ : mapping, optional
        Environment for the password lookup (default ``os.environ``).

    Returns
    -------
    settings : dict
        ``security.protocol`` and, for ``sasl_*``, ``sasl.mechanism``,
        ``sasl.username`` and ``sasl.password``.
    description : str
        One line for the log, without the password.

    Raises
    ------
    CredentialsError
        A ``sasl_*`` protocol without a user name or without a password.
    """
    protocol = config.security_protocol.lower()
    settings = {"security.protocol": protocol}
    if not protocol.startswith("sasl_"):
        return settings, protocol
    if not config.sasl_username:
        raise CredentialsError(f"[outbound] security_protocol = {protocol!r} needs [outbound] sasl_username")
    password, source = load_outbound_password(environ)
    mechanism = config.sasl_mechanism.upper()
    settings.update({"sasl.mechanism": mechanism, "sasl.username": config.sasl_username, "sasl.password": password})
    return settings, f"{protocol} {mechanism} user {config.sasl_username} (password from {source})"


class KafkaSink:
    """Publish outbound messages to a Kafka topic.

    Parameters
    ----------
    bootstrap : str
        ``host:port[,host:port]`` of the outbound cluster.
    topic : str
        Outbound topic.
    max_message_bytes : int
        Largest message (bytes); plans with long observation lists and
        withdrawals are far below the default 16 MB.
    delivery_timeout_s : float
        Time (s) to wait for the acknowledgement of one message.
    extra : mapping, optional
        Further librdkafka settings (e.g. SASL for a remote broker).
    """

    name = "kafka"

    def __init__(
        self,
        bootstrap: str,
        topic: str,
        max_message_bytes: int = 16_000_000,
        delivery_timeout_s: float = 30.0,
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        if not bootstrap:  # refused at load already (tool.overrides.require_sink_broker); bad input, one line
            from ...scheduler_core.errors import InputError

            raise InputError('[outbound] sink = "kafka" needs [outbound] bootstrap (HOST:PORT of the broker the '
                             'plans go to)')
        self.topic = topic
        self.delivery_timeout_s = float(delivery_timeout_s)
        conf: dict[str, Any] = {
            "bootstrap.servers": bootstrap,
            "enable.idempotence": True,
            "acks": "all",
            "message.max.bytes": int(max_message_bytes),
            "compression.type": "zstd",
            "linger.ms": 0,
            "delivery.timeout.ms": int(self.delivery_timeout_s * 1000),
            "client.id": "mushrooms-sink",
        }
        conf.update(extra or {})
        #: whether the outbound cluster answers (readiness, ``mushrooms_broker_up{client="sink"}``)
        self.health = BrokerHealth("sink")
        for key, value in client_settings(self.health, stats_interval_s=5.0).items():
            conf.setdefault(key, value)  # librdkafka's lines into Python logging, repeats rate-limited
        self._producer = confluent_kafka.Producer(conf)
        self._lock = threading.Lock()

    def publish(self, message: Mapping[str, Any]) -> None:
        """Send one message and wait for the broker's acknowledgement.

        Raises
        ------
        PublishError
            When the message is refused or not acknowledged within
            ``delivery_timeout_s``.
        """
        value = strict_json.dumps(message, separators=(",", ":"), sort_keys=False).encode()
        key = _key(message)
        done = threading.Event()
        result: dict[str, Any] = {}

        def on_delivery(err: Any, msg: Any) -> None:
            result["error"] = err
            if msg is not None and err is None:
                result["where"] = (msg.partition(), msg.offset())
            done.set()

        producer = self._producer
        if producer is None:
            raise PublishError(f"the sink of {self.topic} is closed")
        try:
            with self._lock:
                producer.produce(self.topic, value=value, key=key, on_delivery=on_delivery)
        except (BufferError, confluent_kafka.KafkaException) as exc:
            raise PublishError(f"cannot queue message for {self.topic}: {exc}") from None
        deadline = time.monotonic() + self.delivery_timeout_s + 5.0
        while not done.is_set():
            if time.monotonic() > deadline:
                raise PublishError(f"no acknowledgement from {self.topic} within {self.delivery_timeout_s:.0f} s")
            producer.poll(0.1)
        if result.get("error") is not None:
            raise PublishError(f"publish to {self.topic} failed: {result['error']}")
        log.debug("event=kafka_published topic=%s key=%s partition_offset=%s bytes=%d",
                  self.topic, key, result.get("where"), len(value))

    def serve_callbacks(self) -> None:
        """Serve librdkafka's statistics and error callbacks (:attr:`health`) between publishes."""
        producer = self._producer
        if producer is not None:
            producer.poll(0)

    def close(self, timeout_s: float = 10.0) -> None:
        """Flush what is still queued (s of patience), then close the producer: its threads and sockets end.

        A second call does nothing; :meth:`publish` then raises.
        """
        with self._lock:
            producer, self._producer = self._producer, None
        if producer is None:
            return
        producer.flush(timeout_s)
        close = getattr(producer, "close", None)  # confluent-kafka's Producer.close (newer releases)
        if close is not None:
            close()
        # else: the last reference goes here, and its destructor (rd_kafka_destroy) ends threads and sockets


def _key(message: Mapping[str, Any]) -> bytes | None:
    sid = message.get("superevent_id")
    if not sid and isinstance(message.get("event"), Mapping):
        sid = message["event"].get("superevent_id")
    sid = sid or message.get("plan_id")
    return str(sid).encode() if sid else None
