"""The daemon and the bench's ``service`` row take the same supersede decision (``anytime.supersession``).

The real pipeline plans MS181101ab's PRELIMINARY notice (real SQLite state,
real greedy first plan, real hybrid optimisation); the bench's ``service``
row plans the notice's own sky map from the same start.  With a margin no
plan can reach, revision 1 stands in both; with the default margin, the
hybrid's plan, covering much more, is revision 2 in both.
"""

from __future__ import annotations

import base64
import json

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.settings import DaemonConfig
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store
from mushrooms.evaluation.bench import BenchConfig, BenchSettings, run_bench
from mushrooms.scheduler_core import PlanningConfig

from loop_helpers import POLICY, RECEIVED, SUPEREVENT, notice_bytes

#: A 3 h horizon: greedy covers about 0.71 of the map, the hybrid about 0.89 (a clear revision 2).
HYBRID = PlanningConfig(solver="hybrid", objective="coverage", nside=64, time_step_s=600.0, threads=1,
                        time_limit_s=2.0, min_gain=0.0, min_coverage=0.0, horizon_h=3.0, deterministic=True)


def daemon_answer(tmp_path, gain):
    """(revision published last, its coverage, the plan_final reason or None) of the real pipeline."""
    sink = MemorySink()
    p = NoticePipeline(POLICY, HYBRID, Store(tmp_path / "state.sqlite"), sink,
                       daemon=DaemonConfig(supersede_min_gain=gain))
    try:
        out = p.handle(notice_bytes(), "test:notice", RECEIVED)
        assert out.decision == "plan", out
        plans = p.store.plans(SUPEREVENT)
    finally:
        p.store.close()
    last = plans[-1]["document"]
    final = [m for m in sink.messages if m.get("type") == "plan_final"]
    return last, plans[0]["document"], (final[-1]["reason"] if final else None)


def bench_answer(tmp_path, gain, start_iso):
    doc = json.loads(notice_bytes())
    skymap = tmp_path / "MS181101ab.multiorder.fits"
    skymap.write_bytes(base64.b64decode(doc["event"]["skymap"]))
    settings = BenchSettings(config=HYBRID, bench=BenchConfig(legacy_scoring=False), solvers=("service",),
                             n_injections=100, supersede_min_gain=gain, start_iso=start_iso)
    (row,) = run_bench(settings, [skymap])
    return row


@pytest.mark.parametrize("gain, revision", [(1.0, 1), (0.005, 2)], ids=["revision-1-stands", "revision-2-replaces"])
def test_the_daemon_and_the_bench_publish_the_same_revision(tmp_path, gain, revision):
    published, first, reason = daemon_answer(tmp_path, gain)
    row = bench_answer(tmp_path, gain, first["start"])
    assert published["revision"] == revision
    assert row["solver_detail"].startswith(f"revision {revision} ")
    assert row["coverage"] == pytest.approx(published["metrics"]["coverage"], abs=1e-6)
    assert row["n_exposures"] == published["metrics"]["n_exposures"]
    if revision == 1:
        assert row["solver_detail"].startswith("revision 1 (greedy) stands: hybrid not better by 1")
        assert reason.startswith("The first plan stands: the optimised hybrid plan would cover")
    else:
        assert published["metrics"]["coverage"] > first["metrics"]["coverage"]
        assert reason is None
