"""The loop's scenario: a real notice planned by the real pipeline, then what the telescope did.

MS181101ab's PRELIMINARY notice (tests/data/notices/json), re-dated as if it
had been sent live at 2023-04-15T02:55Z (its map is then well placed: the
greedy plan covers 0.985 of it), planned by :class:`NoticePipeline` on a real
SQLite state with the fast test configuration.  The executed record is the
plan's own first exposures, written as the JSON-lines file the loop reads.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Sequence

from astropy.time import Time, TimeDelta

from mushrooms.daemon.loop.poll import ExecutedLoop
from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store
from mushrooms.handlers.executed import write_jsonl
from mushrooms.handlers.policy import PolicyConfig
from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.executed import ExecutedExposure

NOTICES = Path(__file__).resolve().parents[1] / "data" / "notices"
NOTICE = NOTICES / "json" / "MS181101ab-preliminary.json"
SUPEREVENT = "MS181101ab"
#: When the notice is taken as sent (and received 30 s later): the start of a good night for its map.
SENT = "2023-04-15T02:55:00Z"
RECEIVED = datetime(2023, 4, 15, 2, 55, 30, tzinfo=timezone.utc)
#: Greedy at a coarse resolution: a plan in a few seconds; the default 1800 s cadence and 300 s exposures.
PLANNING = PlanningConfig(solver="greedy", nside=64, time_step_s=600.0, min_gain=0.0, min_coverage=0.0)
POLICY = PolicyConfig(allow_mock=True)


def notice_bytes() -> bytes:
    """The notice, re-dated to :data:`SENT` (``time_created`` and ``event.time``)."""
    doc = json.loads(NOTICE.read_bytes())
    doc["time_created"] = doc["event"]["time"] = SENT
    return json.dumps(doc).encode()


def loop_config(executed: Path, **changes: Any) -> LoopConfig:
    return LoopConfig(executed_source=f"file:{executed}", **changes)


def open_pipeline(state: Path, loop: LoopConfig, planning: PlanningConfig = PLANNING) -> NoticePipeline:
    return NoticePipeline(POLICY, planning, Store(state), MemorySink(), loop=loop)


def planned_state(directory: Path, planning: PlanningConfig = PLANNING) -> Path:
    """A state file holding the notice and its plan (revision 1), made once by the real pipeline."""
    state = directory / "planned.sqlite"
    p = open_pipeline(state, LoopConfig(), planning)
    try:
        out = p.handle(notice_bytes(), "test:notice", RECEIVED)
        assert out.decision == "plan" and out.plan_id, out
    finally:
        p.store.close()
    return state


def copy_state(planned: Path, directory: Path) -> Path:
    """A private copy of the planned state file."""
    target = directory / "state.sqlite"
    shutil.copyfile(planned, target)
    return target


def the_plan(p: NoticePipeline) -> dict[str, Any]:
    """The event's current plan document."""
    return p.store.plans(SUPEREVENT)[-1]["document"]


def t(iso: str) -> Time:
    """A plan document's time."""
    return Time(iso.rstrip("Z"), scale="utc")


def executed_like(observations: Sequence[dict[str, Any]], fraction: float = 1.0,
                  status: str = "processed") -> list[ExecutedExposure]:
    """The planned observations as executed at their planned times."""
    return [ExecutedExposure(int(o["field_id"]), o["filter"], t(o["start"]), float(o["exposure_s"]), fraction, status)
            for o in observations]


def write_executed(path: Path, exposures: Sequence[ExecutedExposure]) -> Path:
    return write_jsonl(exposures, path)


def after(iso: str, seconds: float) -> Time:
    return t(iso) + TimeDelta(seconds, format="sec")


def poller(p: NoticePipeline) -> ExecutedLoop:
    return ExecutedLoop(p.loop, p)


def with_loop(p: NoticePipeline, **changes: Any) -> NoticePipeline:
    """The same pipeline's store under other [loop] settings."""
    return NoticePipeline(POLICY, PLANNING, p.store, p.sink, loop=dataclasses.replace(p.loop, **changes))
