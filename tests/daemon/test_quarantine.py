"""A notice that cannot be stored is kept byte for byte in the quarantine
directory and its offset committed; when even that fails it stays
uncommitted (rewound) and is retried.  Real SQLite store, real notice; the
Kafka consumer is replaced by a recorder of commit/rewind calls (the broker
plays no part in this path)."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mushrooms.daemon.kafka.consumer import Received
from mushrooms.daemon.service import Service
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.wiring import open_pipeline
from mushrooms.tool.config import load_config
from mushrooms.tool.overrides import override_config

from daemon_helpers import notice_bytes


@dataclass
class RecordingConsumer:
    committed: list[str] = field(default_factory=list)
    rewound: list[str] = field(default_factory=list)

    def commit(self, received: Received) -> None:
        self.committed.append(received.origin)

    def rewind(self, received: Received) -> None:
        self.rewound.append(received.origin)


def _service(tmp_path: Path, quarantine: str) -> Service:
    cfg = tmp_path / "config.toml"
    cfg.write_text(f'[daemon]\naccept_retries = 2\nquarantine_dir = "{quarantine}"\n'
                   f'[outbound]\ndirectory = "{tmp_path / "outbox"}"\n')
    config = override_config(load_config(str(cfg)), bootstrap="127.0.0.1:9",
                             state=str(tmp_path / "state" / "state.sqlite"), allow_mock=True)
    svc = Service(config, resolve_paths(config.daemon))
    svc.pipeline, close = open_pipeline(svc.config, svc.paths)
    close()  # the store is closed: every accept() now fails as a broken disk would make it
    svc.consumer = RecordingConsumer()
    svc.signals.stop.wait = lambda timeout=None: False  # no back-off sleeps in the test
    return svc


def test_a_notice_that_cannot_be_stored_is_quarantined_and_committed(tmp_path: Path, caplog: Any) -> None:
    raw = notice_bytes("MS181101ab-preliminary.json")
    svc = _service(tmp_path, str(tmp_path / "quarantine"))
    received = Received(value=raw, origin="kafka:igwn.gwalert:0:42", received_at=time.time(), message=None)
    with caplog.at_level(logging.INFO):
        svc._handle(received)
    kept = tmp_path / "quarantine" / "kafka_igwn.gwalert_0_42.bin"
    assert kept.read_bytes() == raw
    assert svc.consumer.committed == ["kafka:igwn.gwalert:0:42"] and svc.consumer.rewound == []
    assert svc.counts["quarantined"] == 1
    text = caplog.text
    assert text.count("event=store_failed") == 2 and "attempt=2/2" in text
    assert "event=notice_quarantined" in text and "decision=quarantined" in text


def test_when_quarantine_fails_too_the_notice_stays_uncommitted(tmp_path: Path, caplog: Any) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("a file where the quarantine directory should be")
    svc = _service(tmp_path, str(blocker / "quarantine"))
    received = Received(value=notice_bytes("MS181101ab-preliminary.json"), origin="kafka:igwn.gwalert:0:7",
                        received_at=time.time(), message=None)
    with caplog.at_level(logging.INFO):
        svc._handle(received)
    assert svc.consumer.committed == [] and svc.consumer.rewound == ["kafka:igwn.gwalert:0:7"]
    assert svc.counts["quarantined"] == 0 and svc.counts["notices"] == 0
    assert "event=quarantine_failed" in caplog.text
