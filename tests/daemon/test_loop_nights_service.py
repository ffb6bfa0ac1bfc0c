"""The service's timers for the following nights (L9): without an executed source, ``nights > 1`` polls anyway."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from mushrooms.daemon.service import Service
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.wiring import open_pipeline
from mushrooms.tool.config import load_config
from mushrooms.tool.overrides import override_config


class RecordingScheduler:
    def __init__(self) -> None:
        self.jobs: list[tuple[str, float]] = []

    def add_job(self, func: Any, trigger: str, seconds: float, id: str, **_: Any) -> None:
        self.jobs.append((id, seconds))


@pytest.mark.parametrize("extra, timers", [
    ("[scheduler]\nnights = 2\n[loop]\npoll_interval_s = 60.0\n", [("nights", 60.0)]),
    ("[scheduler]\nnights = 1\n", []),
    ("[scheduler]\nnights = 2\n[loop]\nexecuted_source = \"file:{tmp}/executed.jsonl\"\npoll_interval_s = 30.0\n",
     [("executed", 30.0)]),  # the loop's poll does the nights itself
])
def test_the_nights_timer_runs_only_with_nights_and_no_source(tmp_path: Path, extra: str,
                                                              timers: list[tuple[str, float]]) -> None:
    cfg = tmp_path / "config.toml"
    cfg.write_text(f'[outbound]\ndirectory = "{tmp_path / "outbox"}"\n' + extra.replace("{tmp}", str(tmp_path)))
    config = override_config(load_config(str(cfg)), bootstrap="127.0.0.1:9",
                             state=str(tmp_path / "state" / "state.sqlite"), allow_mock=True)
    svc = Service(config, resolve_paths(config.daemon))
    svc.pipeline, close = open_pipeline(svc.config, svc.paths)
    try:
        svc.scheduler = RecordingScheduler()
        svc.timers.start_loop(None)
        assert svc.scheduler.jobs == timers
    finally:
        close()
