"""``mushrooms status`` tells that the input broker is down, without the metrics listener (issue 52, finding 10).

Wrong GCN credentials or an unreachable broker left the service "running" with
only ``event=broker_unreachable`` in the log; the broker-down alert needs
the metrics listener, which is off by default.  The daemon now keeps what
it knows of its brokers in the state file, and ``status`` reads it.
"""

from __future__ import annotations

from broker_down_setup import BROKER_DOWN_CONFIG, closed_port, run_status
from daemon_helpers import REPO, Daemon

CONFIG = BROKER_DOWN_CONFIG.format(group="mushrooms-status-broker")


def test_status_says_the_input_broker_is_unreachable_without_the_metrics_listener(daemons, tmp_path) -> None:
    cfg = tmp_path / "config.toml"
    cfg.write_text(CONFIG)
    state = tmp_path / "state.sqlite"
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", f"127.0.0.1:{closed_port()}", "--state",
                          str(state), "--outbox", str(tmp_path / "outbox")])
    daemons.append(d)
    text = d.wait_log("event=broker_unreachable", timeout_s=180)
    assert "metrics_listening" not in text  # the listener is off ([daemon] metrics_address = "")
    beats = text.count("event=heartbeat")
    d.wait_log("event=heartbeat", timeout_s=60, count=beats + 2)  # the daemon has had time to say it
    out = run_status(cfg, state, REPO)
    assert out.returncode == 1, out.stdout + out.stderr
    assert "input broker (consumer): UNREACHABLE since" in out.stdout, out.stdout
    assert "NEEDS ATTENTION" in out.stdout and "input Kafka broker is unreachable" in out.stdout, out.stdout
    d.stop()


def test_status_shows_the_broker_up_again_once_the_daemon_recorded_it(tmp_path, capsys) -> None:
    from mushrooms.cli import main
    from mushrooms.daemon.kafka.broker_log import BrokerHealth
    from mushrooms.daemon.ops.broker_record import BrokerRecord
    from mushrooms.daemon.state.store import Store

    store = Store(tmp_path / "state.sqlite")
    health = BrokerHealth("consumer")
    record = BrokerRecord(store)
    record.update({"consumer": health})  # nothing known yet: nothing written
    health.last_error = "sasl_ssl://kafka.gcn.nasa.gov:9092/bootstrap: SASL authentication error: invalid_token"
    health._set(False)
    record.update({"consumer": health})
    record.update({"consumer": health})  # unchanged: not written again
    store.close()
    assert main(["status", "--state", str(tmp_path / "state.sqlite")]) == 1
    out = capsys.readouterr().out
    assert "input broker (consumer): UNREACHABLE since" in out and "invalid_token" in out
    store = Store(tmp_path / "state.sqlite")
    rows = store.connection().execute("SELECT COUNT(*) FROM incidents WHERE kind='broker'").fetchone()[0]
    assert rows == 1
    health._set(True)
    BrokerRecord(store).update({"consumer": health})
    store.close()
    assert main(["status", "--state", str(tmp_path / "state.sqlite")]) == 0
    out = capsys.readouterr().out
    assert "input broker (consumer): up since" in out and "nothing needs attention" in out
