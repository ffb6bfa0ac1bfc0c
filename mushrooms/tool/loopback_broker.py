"""A Kafka-protocol broker on loopback, for rehearsals: librdkafka's mock cluster.

librdkafka (the C library under confluent-kafka) carries a small in-memory
Kafka cluster, started by a client configured with ``test.mock.num.brokers``;
it lives as long as that client and listens on 127.0.0.1.  The service, a
separate process, connects to it in plaintext (``mushrooms run --bootstrap
HOST:PORT``) like to any broker.  Nothing leaves the machine.
"""

from __future__ import annotations

import time
from typing import Any

__all__ = ["LoopbackBroker", "BrokerError", "MAX_MESSAGE_BYTES"]

#: Largest message the broker takes (bytes): notices carry base64 sky maps of a few MB.
MAX_MESSAGE_BYTES = 16_000_000


class BrokerError(RuntimeError):
    """The loopback broker did not start, or did not take a message."""


class LoopbackBroker:
    """librdkafka's mock cluster (one broker) and a producer bound to it.

    Parameters
    ----------
    timeout_s : float
        How long (s) to wait for the cluster's metadata and for each
        acknowledgement.

    Attributes
    ----------
    bootstrap : str
        ``127.0.0.1:PORT`` of the broker.
    producer : confluent_kafka.Producer
        A producer bound to it, for callers that need more than :meth:`produce`.
    """

    def __init__(self, timeout_s: float = 10.0) -> None:
        import confluent_kafka

        self.timeout_s = float(timeout_s)
        quiet = {"log_level": 3, "message.max.bytes": MAX_MESSAGE_BYTES}
        self._owner: Any = confluent_kafka.Producer({"test.mock.num.brokers": 1, **quiet})
        try:
            brokers = self._owner.list_topics(timeout=self.timeout_s).brokers
        except confluent_kafka.KafkaException as exc:
            raise BrokerError(f"the loopback broker did not start: {exc}") from None
        if not brokers:
            raise BrokerError("the loopback broker did not start: no broker in its metadata")
        b = next(iter(brokers.values()))
        self.bootstrap = f"{b.host}:{b.port}"
        self.producer: Any = confluent_kafka.Producer({"bootstrap.servers": self.bootstrap, "linger.ms": 0,
                                                        **quiet})

    def ensure_topic(self, topic: str) -> None:
        """Create ``topic`` (the mock cluster creates a topic on a metadata request) and wait for its partitions."""
        end = time.monotonic() + self.timeout_s
        while time.monotonic() < end:
            t = self.producer.list_topics(topic, timeout=self.timeout_s).topics.get(topic)
            if t is not None and t.error is None and t.partitions:
                return
            time.sleep(0.1)
        raise BrokerError(f"the loopback broker did not create topic {topic!r}")

    def produce(self, topic: str, value: bytes, key: bytes | None = None) -> tuple[int, int]:
        """Send one message and wait for the broker's acknowledgement; its (partition, offset)."""
        where: list[tuple[int, int]] = []
        errors: list[str] = []

        def delivered(err: Any, msg: Any) -> None:
            if err is not None:
                errors.append(str(err))
            else:
                where.append((msg.partition(), msg.offset()))

        self.producer.produce(topic, value=value, key=key, on_delivery=delivered)
        left = self.producer.flush(self.timeout_s)
        if errors or left or not where:
            raise BrokerError(f"the loopback broker did not take the message on {topic!r}: "
                              f"{errors[0] if errors else 'no acknowledgement'}")
        return where[0]

    def close(self) -> None:
        """Flush and drop the clients; the cluster goes with its owner."""
        self.producer.flush(1.0)
        self._owner.flush(1.0)
        self.producer = self._owner = None

    def __enter__(self) -> "LoopbackBroker":
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._owner is not None:
            self.close()
