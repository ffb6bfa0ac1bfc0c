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


def test_a_kafka_sink_without_a_broker_is_refused_at_load_in_one_line(tmp_path):
    """``[outbound] sink = "kafka"`` with no ``bootstrap`` (nor ``[kafka] bootstrap`` or ``--bootstrap``): a
    ValueError deep in the sink once made ``run``/``trigger`` say "internal error ... exit 70" (issue 52 follow-up).
    """
    import argparse
    import os
    import subprocess
    import sys
    from pathlib import Path

    import pytest

    from mushrooms.tool.config import ConfigError
    from mushrooms.tool.overrides import effective_config

    root = Path(__file__).resolve().parents[1]
    cfg = tmp_path / "config.toml"
    cfg.write_text('[outbound]\nsink = "kafka"\ntopic = "plans"\n')
    args = argparse.Namespace(config=str(cfg), bootstrap=None, outbox=None, state=None, allow_mock=False)
    with pytest.raises(ConfigError, match=r'\[outbound\] sink = "kafka" needs \[outbound\] bootstrap'):
        effective_config(args)
    args.bootstrap = "127.0.0.1:9092"  # a local broker given on the command line is the sink's too
    assert effective_config(args).outbound.bootstrap == "127.0.0.1:9092"
    args.bootstrap, args.outbox = None, str(tmp_path / "out")  # --outbox replaces the Kafka sink
    assert effective_config(args).outbound.sink == "directory"

    env = {k: v for k, v in os.environ.items() if k != "MUSHROOMS_CONFIG"}
    env.update(PYTHONPATH=str(root), GCN_CLIENT_ID="id", GCN_CLIENT_SECRET="secret")
    notice = root / "mushrooms" / "data" / "demo" / "MS260605l-preliminary.json"
    for command in (["trigger", str(notice)], ["run"]):
        r = subprocess.run([sys.executable, "-m", "mushrooms.cli", "--log-level", "WARNING", *command, "--config",
                            str(cfg), "--state", str(tmp_path / "state.sqlite")], capture_output=True, text=True,
                           cwd=tmp_path, env=env, timeout=120)  # a hang guard
        assert r.returncode == 2, r.stderr
        assert r.stderr.count("\n") == 1 and "internal error" not in r.stderr, r.stderr
        assert f'mushrooms {command[0]}: error: {cfg}: [outbound] sink = "kafka" needs [outbound] bootstrap' \
            in r.stderr, r.stderr
    assert not (tmp_path / "state.sqlite").exists()  # refused before anything was created
