"""Command-line overrides of the configuration: one function, used by run, trigger, replay and the demo."""

from __future__ import annotations

import dataclasses

from mushrooms.tool.config import Config
from mushrooms.tool.overrides import override_config


def test_no_override_is_the_same_config():
    c = Config()
    assert override_config(c) == c


def test_each_flag_changes_its_key_only():
    c = Config()
    o = override_config(c, allow_mock=True, solver="greedy", outbox="out", state="s.sqlite")
    assert o.policy.allow_mock is True and o.scheduler.solver == "greedy"
    assert (o.outbound.sink, o.outbound.directory, o.daemon.state_path) == ("directory", "out", "s.sqlite")
    assert dataclasses.replace(o.policy, allow_mock=c.policy.allow_mock) == c.policy
    assert dataclasses.replace(o.scheduler, solver=c.scheduler.solver) == c.scheduler
    assert o.kafka == c.kafka and o.export == c.export


def test_bootstrap_is_the_kafka_sinks_broker_unless_it_has_its_own():
    c = Config()
    kafka_sink = dataclasses.replace(c, outbound=dataclasses.replace(c.outbound, sink="kafka", bootstrap=""))
    o = override_config(kafka_sink, bootstrap="127.0.0.1:9092")
    assert (o.kafka.bootstrap, o.outbound.bootstrap) == ("127.0.0.1:9092", "127.0.0.1:9092")
    own = dataclasses.replace(kafka_sink, outbound=dataclasses.replace(kafka_sink.outbound, bootstrap="sink:9093"))
    assert override_config(own, bootstrap="127.0.0.1:9092").outbound.bootstrap == "sink:9093"
