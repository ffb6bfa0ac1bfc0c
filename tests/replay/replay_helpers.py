"""Shared bits of the pipeline/replay tests: real notices, a fast greedy config."""

from __future__ import annotations

import json
from datetime import datetime
from functools import lru_cache
from pathlib import Path
from typing import Any

from mushrooms.tool.config import Config
from mushrooms.handlers.policy import PolicyConfig
from mushrooms.scheduler_core import PlanningConfig

NOTICES = Path(__file__).resolve().parents[1] / "data" / "notices"

#: greedy at a coarse resolution and time step: each plan takes one to two seconds; these mock
#: events (MS181101ab is ~22 deg from the Sun) get a plan however little it covers (min_coverage 0)
FAST = Config(scheduler=PlanningConfig(solver="greedy", nside=64, time_step_s=600.0, min_gain=0.0, min_coverage=0.0),
              policy=PolicyConfig(allow_mock=True))


@lru_cache(maxsize=None)
def raw(rel: str) -> bytes:
    return (NOTICES / rel).read_bytes()


def mutated(rel: str, **event_changes: Any) -> bytes:
    d = json.loads(raw(rel))
    d["event"].update(event_changes)
    return json.dumps(d).encode()


def created(rel: str) -> datetime:
    """The notice's own time_created (used as the receipt clock, as replay does)."""
    from mushrooms.handlers.alert import parse_notice

    return parse_notice(raw(rel)).time_created
