"""The directory sink writes whole files, atomically, named after the message."""

from __future__ import annotations

import json
import os

import pytest

from mushrooms.daemon.sinks import DirectorySink, Sink, SinkError, message_key


def test_writes_one_file_per_message_and_redelivery_overwrites(tmp_path):
    sink = DirectorySink(tmp_path / "out")
    assert isinstance(sink, Sink)
    sink.publish({"type": "plan", "plan_id": "mushrooms-abc", "coverage": 0.1})
    sink.publish({"type": "plan", "plan_id": "mushrooms-abc", "coverage": 0.2})
    sink.publish({"type": "withdrawal", "withdrawal_id": "withdrawal-S1-x", "plan_ids": ["mushrooms-abc"]})
    names = sorted(os.listdir(tmp_path / "out"))
    assert names == ["mushrooms-abc.json", "withdrawal-S1-x.json"]  # no temporary files left
    assert json.loads((tmp_path / "out" / "mushrooms-abc.json").read_text())["coverage"] == 0.2
    assert os.stat(tmp_path / "out" / "mushrooms-abc.json").st_mode & 0o044 == 0o044


def test_unsafe_keys_cannot_escape_the_directory(tmp_path):
    sink = DirectorySink(tmp_path)
    sink.publish({"type": "plan", "plan_id": "../../evil"})
    assert sorted(os.listdir(tmp_path)) == [".._.._evil.json"]


def test_message_without_key_is_an_error(tmp_path):
    with pytest.raises(SinkError):
        DirectorySink(tmp_path).publish({"type": "plan"})
    assert message_key({"type": "withdrawal", "withdrawal_id": "w"}) == "w"


def test_failed_write_leaves_no_partial_file(tmp_path, monkeypatch):
    sink = DirectorySink(tmp_path)
    sink.publish({"type": "plan", "plan_id": "p", "v": 1})

    def disk_full(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    with pytest.raises(OSError):
        sink.publish({"type": "plan", "plan_id": "p", "v": 2})
    assert os.listdir(tmp_path) == ["p.json"]  # the old file, whole; no temporary file left
    assert json.loads((tmp_path / "p.json").read_text())["v"] == 1
