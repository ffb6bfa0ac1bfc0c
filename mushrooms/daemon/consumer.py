"""The GCN Kafka input: build the consumer, read notices, commit offsets.

Offsets are committed by hand (``enable.auto.commit=false``), one message at
a time and synchronously, only after the service has stored what it decided
about that message.  A crash between the two redelivers the message: the
store recognises it and the plan id is the same, so redelivery is harmless.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any, Sequence

import confluent_kafka
import gcn_kafka

from .credentials import Credentials, load_credentials
from .kafka_logging import BrokerHealth, client_settings
from .settings import KafkaConfig

__all__ = ["Received", "NoticeConsumer", "consumer_config"]

log = logging.getLogger(__name__)

#: Period (s) of the retries of a manual assignment whose topic does not exist yet.
TOPIC_RETRY_S = 5.0


@dataclass(frozen=True)
class Received:
    """One message taken from the topic.

    Attributes
    ----------
    value : bytes
        The notice as received.
    origin : str
        ``kafka:TOPIC:PARTITION:OFFSET``: where it came from, for the store.
    received_at : float
        Wall-clock time (s since the epoch) when ``consume()`` returned it.
    """

    value: bytes
    origin: str
    received_at: float
    message: Any  # the confluent_kafka.Message, needed to commit


def consumer_config(config: KafkaConfig, instance_id: str | None = None) -> dict[str, Any]:
    """librdkafka settings of the input consumer (without credentials).

    ``instance_id`` (``group`` mode only) makes the consumer a static group
    member (``group.instance.id``): a restart rejoins as the same member.
    """
    conf: dict[str, Any] = {
        "group.id": config.group_id,
        "enable.auto.commit": False,
        "enable.auto.offset.store": False,
        "auto.offset.reset": config.offset_reset,
        "session.timeout.ms": int(config.session_timeout_s * 1000),
        "fetch.max.bytes": int(config.max_message_bytes),
        "max.partition.fetch.bytes": int(config.max_message_bytes),
        "receive.message.max.bytes": int(config.max_message_bytes) + 1_000_000,
        "client.id": "mushrooms",
    }
    if instance_id and config.assignment == "group":
        conf["group.instance.id"] = instance_id
    if config.bootstrap:
        conf["bootstrap.servers"] = config.bootstrap
        conf["security.protocol"] = "plaintext"
    return conf


class NoticeConsumer:
    """gcn-kafka consumer with manual, synchronous offset commits.

    Parameters
    ----------
    config : KafkaConfig
        ``[kafka]`` settings.  With ``bootstrap`` set the consumer connects in
        plaintext without credentials (local broker); otherwise it connects
        to GCN (``domain``) with OIDC credentials from the environment or
        systemd credentials.
    credentials : Credentials, optional
        Overrides the lookup (tests).
    instance_id : str, optional
        Static group membership (:func:`~.settings.group_instance_id`).

    In ``manual`` mode a topic that does not exist yet is waited for (one
    warning, then a retry every :data:`TOPIC_RETRY_S`; :meth:`poll` returns
    None meanwhile), so the daemon keeps its loop, signals and watchdog.
    """

    def __init__(self, config: KafkaConfig, credentials: Credentials | None = None,
                 instance_id: str | None = None) -> None:
        self.config = config
        self.instance_id = instance_id if config.assignment == "group" else None
        self._assigned = config.assignment == "group"
        self._retry_at = 0.0
        #: whether the input cluster answers (heartbeat, systemd status)
        self.health = BrokerHealth("consumer")
        conf = consumer_config(config, self.instance_id) | client_settings(self.health, stats_interval_s=5.0)
        if config.bootstrap:
            self._consumer = gcn_kafka.Consumer(config=conf)
            where = f"{config.bootstrap} (plaintext, no credentials)"
        else:
            creds = credentials or load_credentials()
            self._consumer = gcn_kafka.Consumer(
                config=conf, client_id=creds.client_id, client_secret=creds.client_secret,
                domain=config.domain,
            )
            where = f"kafka.{config.domain} (client id {creds.client_id}, from {creds.source})"
        log.info("event=consumer_started broker=%s topics=%s group_id=%s assignment=%s group_instance_id=%s",
                 where, ",".join(config.topics), config.group_id, config.assignment, self.instance_id or "-")
        self._start(list(config.topics))

    def _start(self, topics: list[str]) -> None:
        if self.config.assignment == "group":
            self._consumer.subscribe(topics, on_assign=_log_assign, on_revoke=_log_revoke)
            return
        self._assign_manually(topics, first=True)

    def _assign_manually(self, topics: list[str], first: bool = False) -> bool:
        """Assign every partition of every topic, from the group's committed offsets; False while a topic is missing."""
        self._retry_at = time.monotonic() + TOPIC_RETRY_S
        try:
            md = self._consumer.list_topics(timeout=30)
            parts = []
            missing = []
            for topic in topics:
                tmd = md.topics.get(topic)
                if tmd is None or tmd.error is not None or not tmd.partitions:
                    # the topic may not exist yet: ask for it again (auto-creation where allowed)
                    tmd = self._consumer.list_topics(topic, timeout=30).topics.get(topic)
                if tmd is None or tmd.error is not None or not tmd.partitions:
                    missing.append(topic)
                    continue
                parts += [confluent_kafka.TopicPartition(topic, p) for p in sorted(tmd.partitions)]
            if missing:
                if first:
                    log.warning("event=topic_missing topics=%s mode=manual: waiting for the topic to exist "
                                "(retry every %.0f s; nothing is consumed meanwhile)", ",".join(missing),
                                TOPIC_RETRY_S)
                return False
            committed = self._consumer.committed(parts, timeout=30)
        except confluent_kafka.KafkaException as exc:
            log.warning("event=manual_assignment_failed error=%r (retry in %.0f s)", str(exc), TOPIC_RETRY_S)
            return False
        self._consumer.assign(committed)
        self._assigned = True
        log.info("event=partitions_assigned mode=manual positions=%s",
                 " ".join(f"{tp.topic}[{tp.partition}]@{tp.offset}" for tp in committed))
        return True

    def poll(self, timeout_s: float | None = None) -> Received | None:
        """Wait up to ``timeout_s`` (s) for one notice; None when none came.

        Broker and partition errors are logged, never raised: the client
        reconnects on its own.
        """
        wait = self.config.poll_timeout_s if timeout_s is None else timeout_s
        if not self._assigned:
            if time.monotonic() < self._retry_at or not self._assign_manually(list(self.config.topics)):
                time.sleep(wait)
                return None
        msgs = self._consumer.consume(1, wait)
        if not msgs:
            return None
        msg = msgs[0]
        err = msg.error()
        if err is not None:
            if err.code() == confluent_kafka.KafkaError._PARTITION_EOF:
                return None
            log.warning("event=kafka_error error=%r fatal=%s", str(err), err.fatal())
            if err.fatal():
                raise RuntimeError(f"fatal Kafka error: {err}")
            return None
        self.health.on_message()
        value = msg.value() or b""
        return Received(
            value=value,
            origin=f"kafka:{msg.topic()}:{msg.partition()}:{msg.offset()}",
            received_at=time.time(),
            message=msg,
        )

    def commit(self, received: Received) -> None:
        """Commit the offset after ``received`` (synchronously)."""
        self._consumer.commit(message=received.message, asynchronous=False)

    def rewind(self, received: Received) -> None:
        """Read ``received`` again on the next poll (its storage failed)."""
        msg = received.message
        self._consumer.seek(confluent_kafka.TopicPartition(msg.topic(), msg.partition(), msg.offset()))

    def close(self) -> None:
        """Leave the group (uncommitted messages are redelivered later)."""
        try:
            self._consumer.close()
        except RuntimeError:
            pass


def _log_assign(consumer: Any, partitions: Sequence[Any]) -> None:
    log.info("event=partitions_assigned mode=group partitions=%s",
             " ".join(f"{tp.topic}[{tp.partition}]" for tp in partitions) or "-")


def _log_revoke(consumer: Any, partitions: Sequence[Any]) -> None:
    log.info("event=partitions_revoked partitions=%s",
             " ".join(f"{tp.topic}[{tp.partition}]" for tp in partitions) or "-")
