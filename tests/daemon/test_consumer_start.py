"""The input consumer's start: static group membership per installation, and a
manual assignment before the topic exists waits instead of exiting 70.  Real mock broker."""

from __future__ import annotations

import logging
import time
from pathlib import Path

import pytest

from mushrooms.daemon.kafka.consumer import NoticeConsumer, consumer_config
from mushrooms.daemon.settings import KafkaConfig, group_instance_id


def test_group_instance_id_is_stable_per_installation_and_configurable(tmp_path: Path) -> None:
    cfg = KafkaConfig()
    a = group_instance_id(cfg, tmp_path / "a" / "state.sqlite", host="ztf-node1")
    assert a == group_instance_id(cfg, tmp_path / "a" / "state.sqlite", host="ztf-node1")  # every restart
    assert a != group_instance_id(cfg, tmp_path / "b" / "state.sqlite", host="ztf-node1")  # another installation
    assert a.startswith("mushrooms-ztf-node1-")
    assert group_instance_id(KafkaConfig(instance_id="site-a"), tmp_path / "x") == "site-a"
    assert group_instance_id(KafkaConfig(instance_id="none"), tmp_path / "x") is None
    assert consumer_config(cfg, a)["group.instance.id"] == a
    assert "group.instance.id" not in consumer_config(KafkaConfig(assignment="manual"), a)
    with pytest.raises(ValueError, match="instance_id"):
        KafkaConfig(instance_id="two words")


def test_the_service_consumer_carries_the_derived_instance_id(broker, tmp_path: Path) -> None:
    topic = f"static-{time.time_ns()}"
    broker.ensure_topic(topic)
    iid = group_instance_id(KafkaConfig(), tmp_path / "state.sqlite")
    c = NoticeConsumer(KafkaConfig(topics=(topic,), group_id=f"g-{time.time_ns()}", bootstrap=broker.bootstrap,
                                   session_timeout_s=6.0), instance_id=iid)
    try:
        assert c.instance_id == iid
    finally:
        c.close()


def test_manual_assignment_before_the_topic_exists_waits_for_it(broker, caplog) -> None:
    topic = f"later-{time.time_ns()}"
    cfg = KafkaConfig(topics=(topic,), group_id=f"g-{time.time_ns()}", bootstrap=broker.bootstrap,
                      assignment="manual", poll_timeout_s=0.2)
    with caplog.at_level(logging.WARNING, logger="mushrooms.daemon.consumer"):
        c = NoticeConsumer(cfg)  # raised RuntimeError("topic ... has no partitions"): exit 70
    try:
        assert "event=topic_missing" in caplog.text
        assert c.poll() is None
        broker.ensure_topic(topic)
        broker.produce(topic, b"first notice", key=b"k")
        got = None
        end = time.monotonic() + 60
        while got is None and time.monotonic() < end:
            got = c.poll()
        assert got is not None and got.value == b"first notice"
    finally:
        c.close()
