"""Kafka clients that keep the GCN session: what the project requires, and what a start refuses.

gcn-kafka before 0.3.4 loses its token after about an hour (``invalid_token``); 0.3.4 needs
confluent-kafka >= 2.11 (``mushrooms/daemon/kafka/versions.py`` says why).  A start on GCN with an
older pair is refused with one line before anything is touched; the session itself is tested across
token refreshes in ``test_token_refresh.py``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

from daemon_helpers import REPO

GCN_CONFIG = """
[scheduler]
solver = "greedy"
nside = 64

[kafka]
topics = ["igwn.gwalert"]
assignment = "manual"

[outbound]
sink = "directory"
"""


def kafka_client_problem(**kw):
    from mushrooms.daemon.kafka.versions import kafka_client_problem as check

    return check(**kw)


def _requirement(name: str) -> str:
    deps = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    found = [d for d in deps if re.match(rf"{re.escape(name)}\s*[<>=!~ ]", d)]
    assert len(found) == 1, found
    return found[0].replace(" ", "")


def test_pyproject_requires_the_kafka_clients_that_keep_the_gcn_token():
    assert _requirement("gcn-kafka").startswith("gcn-kafka>=0.3.4")
    assert _requirement("confluent-kafka").startswith("confluent-kafka>=2.11")


def test_the_installed_clients_pass_the_start_check():
    assert kafka_client_problem() is None


def test_an_old_gcn_kafka_is_one_line_naming_what_and_why():
    installed = {"gcn-kafka": "0.3.3", "confluent-kafka": "2.16.2"}
    line = kafka_client_problem(version=installed.__getitem__, librdkafka=lambda: "2.16.0")
    assert "gcn-kafka 0.3.3 (needs >= 0.3.4)" in line and "confluent-kafka" not in line.split("installed")[0]
    assert "invalid_token" in line and "\n" not in line


def test_an_old_confluent_kafka_or_librdkafka_is_named():
    installed = {"gcn-kafka": "0.3.4", "confluent-kafka": "2.10.1"}
    line = kafka_client_problem(version=installed.__getitem__, librdkafka=lambda: "2.10.1")
    assert "confluent-kafka 2.10.1 (needs >= 2.11.0)" in line and "librdkafka 2.10.1 (needs >= 2.11.0)" in line
    installed = {"gcn-kafka": "0.3.4", "confluent-kafka": "2.11.0"}  # a source build on an old system librdkafka
    assert "librdkafka 2.3.0" in kafka_client_problem(version=installed.__getitem__, librdkafka=lambda: "2.3.0")
    assert kafka_client_problem(version={"gcn-kafka": "0.3.4rc1", "confluent-kafka": "2.11.0"}.__getitem__,
                                librdkafka=lambda: "2.11.1") is None


def test_run_on_gcn_with_an_old_gcn_kafka_is_refused_in_one_line_before_touching_state(tmp_path):
    """The installed metadata says gcn-kafka 0.3.3 (a dist-info first on the path): exit 2, one line."""
    fake = tmp_path / "site"
    info = fake / "gcn_kafka-0.3.3.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: gcn-kafka\nVersion: 0.3.3\n")
    cfg = tmp_path / "config.toml"  # no [kafka] bootstrap: GCN, with credentials
    cfg.write_text(GCN_CONFIG)
    env = {k: v for k, v in os.environ.items() if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC")}
    env.update(PYTHONPATH=os.pathsep.join([str(fake), str(REPO)]), GCN_CLIENT_ID="mushrooms-test",
               GCN_CLIENT_SECRET="not-a-real-secret-0123456789")
    proc = subprocess.run([sys.executable, "-m", "mushrooms.cli", "run", "--config", str(cfg)], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=60)  # a hang guard only (it exits in seconds)
    err = [ln for ln in proc.stderr.splitlines() if "error" in ln]
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert len(err) == 1 and "gcn-kafka 0.3.3 (needs >= 0.3.4)" in err[0], proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "not-a-real-secret" not in proc.stderr
    assert not list(tmp_path.glob("*.sqlite*")) and not (tmp_path / "mushrooms.pid").exists()
