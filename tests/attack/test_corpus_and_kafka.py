"""Every hostile message gets exactly one decision row and no exception;
librdkafka's log goes through Python logging with repeats rate-limited,
and broker reachability is known (real librdkafka clients: an unreachable
address and the mock cluster on loopback)."""

from __future__ import annotations

import logging
import time

import confluent_kafka
import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.settings import KafkaConfig
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store

from attack_helpers import FAST, hostile_corpus, received_at


def test_every_hostile_message_gets_exactly_one_decision_row(tmp_path) -> None:
    store = Store(tmp_path / "s.sqlite")
    p = NoticePipeline.from_config(FAST, store, MemorySink())
    corpus = hostile_corpus()
    assert len(corpus) >= 39
    outcomes = {}
    for i, (name, raw) in enumerate(corpus):
        acc = p.accept(raw, f"attack:{i}:{name}", received_at())
        outcomes[name] = acc.action
        if acc.job is not None:  # the bad-map ones are caught when the job reads the map
            assert p.run_job(acc.job).decision in ("plan", "rejected", "ignore")
    counts = store.connection().execute(
        "SELECT n.notice_id, COUNT(d.decision_id) FROM notices n LEFT JOIN decisions d USING(notice_id)"
        " GROUP BY n.notice_id").fetchall()
    assert len(counts) == len(corpus) and all(c == 1 for _, c in counts)
    for name in ("time 2200", "time 9999", "created 9999", "xml entity", "utf-16 voevent entity", "oversize"):
        assert outcomes[name] == "rejected", (name, outcomes[name])
    for row in store.decisions():
        assert "\n" not in row["reason"]
    store.close()


def test_repeats_of_one_kind_are_suppressed_and_counted() -> None:
    from mushrooms.daemon.kafka.broker_log import RepeatFilter

    now = [0.0]
    f = RepeatFilter(window_s=60, clock=lambda: now[0])

    def rec(msg: str) -> logging.LogRecord:
        return logging.LogRecord("mushrooms.kafka.librdkafka", logging.ERROR, __file__, 1, msg, None, None)

    passed = [f.filter(rec(f"Connect failed (after {i}ms in state CONNECT)")) for i in range(200)]
    assert passed.count(True) == 1 and f.suppressed == 199
    assert f.filter(rec("another kind of line"))
    now[0] = 61.0
    r = rec("Connect failed (after 5ms in state CONNECT)")
    assert f.filter(r) and "199 similar line(s) suppressed" in r.getMessage()


def _poll(consumer, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        consumer.poll(0.2)


def test_an_unreachable_broker_is_reported_once_not_twenty_times_a_second(caplog) -> None:
    from mushrooms.daemon.kafka.consumer import NoticeConsumer

    with caplog.at_level(logging.INFO):
        c = NoticeConsumer(KafkaConfig(bootstrap="127.0.0.1:9", topics=("t",), group_id="g", assignment="group"))
        try:
            _poll(c, 7.0)
            assert c.health.describe() == "down"
            assert "UNREACHABLE" in c.health.status_text()
        finally:
            c.close()
    rd = [r for r in caplog.records if r.name == "mushrooms.kafka.librdkafka"]
    assert 1 <= len(rd) <= 5, len(rd)  # librdkafka tried ~20 times a second; one line of each kind gets out
    assert sum("event=broker_unreachable" in r.getMessage() for r in caplog.records) == 1


def test_a_reachable_broker_is_reported_up() -> None:
    from mushrooms.daemon.kafka.consumer import NoticeConsumer
    from mushrooms.tool.loopback_broker import LoopbackBroker

    with LoopbackBroker() as broker:
        c = NoticeConsumer(KafkaConfig(bootstrap=broker.bootstrap, topics=("t",), group_id="g", assignment="group"))
        try:
            end = time.monotonic() + 30
            while c.health.up is not True and time.monotonic() < end:
                c.poll(0.2)
            assert c.health.describe() == "up" and c.health.status_text() == "broker: up"
        finally:
            c.close()


def test_health_follows_librdkafka_errors() -> None:
    from mushrooms.daemon.kafka.broker_log import BrokerHealth

    h = BrokerHealth("test")
    assert h.describe() == "unknown"
    h.on_error(confluent_kafka.KafkaError(confluent_kafka.KafkaError._ALL_BROKERS_DOWN, "1/1 brokers are down"))
    assert h.describe() == "down" and "brokers are down" in h.status_text()
    h.on_stats('{"brokers": {"b:1/1": {"state": "UP"}}}')
    assert h.describe() == "up"


@pytest.mark.parametrize("bad", ["not json", "{}"])
def test_health_ignores_odd_statistics(bad: str) -> None:
    from mushrooms.daemon.kafka.broker_log import BrokerHealth

    h = BrokerHealth("test")
    h.on_stats(bad)
    assert h.describe() in ("unknown", "down")
