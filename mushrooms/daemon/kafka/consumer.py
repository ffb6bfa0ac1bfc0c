"""The GCN Kafka input: build the consumer, read notices, commit offsets.

Offsets are committed by hand (``enable.auto.commit=false``), one message at
a time and synchronously, only after the service has stored what it decided
about that message.  A crash between the two redelivers the message: the
store recognises it and the plan id is the same, so redelivery is harmless.

No silent loss: when partitions are assigned the consumer compares the
group's committed offsets with each partition's log start, and while
consuming it compares every message's offset with the one it expected
next.  Messages gone in between (deleted by retention while the service was
down: librdkafka then resets to the log start with only a warning, since
``auto.offset.reset = earliest``) are logged at ERROR
(``event=offset_jump ... skipped=N``) and handed to ``on_offset_jump``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import confluent_kafka
import gcn_kafka

from ..credentials import Credentials, load_credentials
from .broker_log import BrokerHealth, client_settings
from ..settings import KafkaConfig
from .versions import require_kafka_clients

__all__ = ["Received", "NoticeConsumer", "consumer_config", "OffsetJump"]

#: ``on_offset_jump(topic, partition, expected, got, skipped, cause)``: messages were skipped.
OffsetJump = Callable[[str, int, int, int, int, str], None]

log = logging.getLogger("mushrooms.daemon.consumer")

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
    on_offset_jump : callable, optional
        Told about every offset jump (:data:`OffsetJump`), after the ERROR line.
    instance_id : str, optional
        Static group membership (:func:`~.settings.group_instance_id`).
    overrides : mapping, optional
        librdkafka settings laid over the service's and gcn-kafka's (tests: a
        loopback OAUTHBEARER broker and token endpoint in place of GCN's).

    On GCN (no ``bootstrap``) the Kafka clients must be recent enough to keep
    the session past its token (:mod:`~.versions`): an older pair raises
    :class:`~.versions.KafkaClientTooOld` (one line, exit status 2).

    In ``manual`` mode a topic that does not exist yet is waited for (one
    warning, then a retry every :data:`TOPIC_RETRY_S`; :meth:`poll` returns
    None meanwhile), so the daemon keeps its loop, signals and watchdog.
    """

    def __init__(self, config: KafkaConfig, credentials: Credentials | None = None,
                 on_offset_jump: OffsetJump | None = None, instance_id: str | None = None,
                 overrides: Mapping[str, Any] | None = None) -> None:
        self.config = config
        self.on_offset_jump = on_offset_jump
        self.instance_id = instance_id if config.assignment == "group" else None
        self._assigned = config.assignment == "group"
        self._retry_at = 0.0
        #: (topic, partition) currently assigned; empty until the group (or manual mode) assigns them
        self.assigned: set[tuple[str, int]] = set()
        #: monotonic time since which the consumer waits for an assignment (None once it has one)
        self.waiting_since: float | None = time.monotonic()
        self._next: dict[tuple[str, int], int] = {}  # offset expected next, per partition
        #: whether the input cluster answers (heartbeat, systemd status)
        self.health = BrokerHealth("consumer")
        conf = consumer_config(config, self.instance_id) | client_settings(self.health, stats_interval_s=5.0)
        conf |= dict(overrides or {})
        if config.bootstrap:
            self._consumer = gcn_kafka.Consumer(config=conf)
            where = f"{config.bootstrap} (plaintext, no credentials)"
        else:
            require_kafka_clients()
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
            self._consumer.subscribe(topics, on_assign=self._on_assign, on_revoke=self._on_revoke)
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
            self._expect(committed)
        except confluent_kafka.KafkaException as exc:
            log.warning("event=manual_assignment_failed error=%r (retry in %.0f s)", str(exc), TOPIC_RETRY_S)
            return False
        self._consumer.assign(committed)
        self._assigned = True
        log.info("event=partitions_assigned mode=manual positions=%s",
                 " ".join(f"{tp.topic}[{tp.partition}]@{tp.offset}" for tp in committed))
        return True

    # -- assignment and offset continuity -------------------------------
    def _on_assign(self, consumer: Any, partitions: Sequence[Any]) -> None:
        _log_assign(consumer, partitions)
        try:
            self._expect(consumer.committed(list(partitions), timeout=10))
        except Exception as exc:  # the check starts with the next message instead
            log.warning("event=offset_check_unavailable error=%r", str(exc))
            self._mark_assigned(partitions)

    def _on_revoke(self, consumer: Any, partitions: Sequence[Any]) -> None:
        _log_revoke(consumer, partitions)
        for tp in partitions:
            self.assigned.discard((tp.topic, tp.partition))
            self._next.pop((tp.topic, tp.partition), None)
        if not self.assigned:
            self.waiting_since = time.monotonic()

    def _mark_assigned(self, partitions: Sequence[Any]) -> None:
        self.assigned.update((tp.topic, tp.partition) for tp in partitions)
        if self.assigned:
            self.waiting_since = None

    def _expect(self, committed: Sequence[Any]) -> None:
        """Remember where each partition must continue; a committed offset below the log start is a jump."""
        for tp in committed:
            key = (tp.topic, tp.partition)
            if tp.offset < 0:  # nothing committed: a new group starts where offset_reset says
                self._next.pop(key, None)
                continue
            self._next[key] = tp.offset
            try:
                low, high = self._consumer.get_watermark_offsets(
                    confluent_kafka.TopicPartition(tp.topic, tp.partition), timeout=10, cached=False)
            except Exception as exc:
                log.warning("event=offset_check_unavailable topic=%s partition=%d error=%r", tp.topic,
                            tp.partition, str(exc))
                continue
            if tp.offset < low:
                self._jump(tp.topic, tp.partition, tp.offset, low,
                           "committed offset below the log start: deleted by retention before it was read")
                self._next[key] = low
            elif tp.offset > high:
                log.warning("event=offset_beyond_end topic=%s partition=%d committed=%d high=%d "
                            "(topic recreated or truncated? the consumer resets to %s)", tp.topic, tp.partition,
                            tp.offset, high, self.config.offset_reset)
                self._next.pop(key, None)
        self._mark_assigned(committed)

    def _check(self, msg: Any) -> None:
        key = (msg.topic(), msg.partition())
        expected = self._next.get(key)
        self._next[key] = msg.offset() + 1
        if expected is None or msg.offset() <= expected:
            return
        try:
            low = self._consumer.get_watermark_offsets(
                confluent_kafka.TopicPartition(msg.topic(), msg.partition()), timeout=5, cached=False)[0]
        except Exception:
            low = None
        if low is not None and low <= expected:  # nothing was deleted: offsets of control records (transactions)
            log.warning("event=offset_gap topic=%s partition=%d expected=%d got=%d log_start=%d (no message "
                        "deleted: transaction markers or compaction)", msg.topic(), msg.partition(), expected,
                        msg.offset(), low)
            return
        self._jump(msg.topic(), msg.partition(), expected, msg.offset(),
                   "messages deleted by retention while waiting to be read")

    def _jump(self, topic: str, partition: int, expected: int, got: int, cause: str) -> None:
        skipped = got - expected
        log.error("event=offset_jump topic=%s partition=%d expected=%d got=%d skipped=%d cause=%r "
                  "(these messages were never seen by the service)", topic, partition, expected, got, skipped, cause)
        if self.on_offset_jump is not None:
            try:
                self.on_offset_jump(topic, partition, expected, got, skipped, cause)
            except Exception:
                log.exception("event=offset_jump_callback_failed")

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
        self._check(msg)
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
        self._next[(msg.topic(), msg.partition())] = msg.offset()

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
