"""Closures and the nights' edges through the real pipeline (``executed.md`` L13-L15).

The loop's scenario under ``[scheduler] nights = 2`` (``loop_helpers``:
MS181101ab re-dated to 2023-04-15T02:55Z, planned by the real pipeline on
real SQLite with greedy); the poll's clock is the night's (``now=``).
"""

from __future__ import annotations

import logging
import re

from mushrooms.daemon.loop.poll import ExecutedLoop
from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.daemon.planning.replans import replan_jobs

from loop_helpers import SUPEREVENT, copy_state, executed_like, loop_config, open_pipeline, t, the_plan, write_executed
from test_loop_nights import TWO, at, nights, planned_two  # noqa: F401  (pytest fixtures)


def test_a_closure_into_night_two_is_kept_by_night_twos_evening(planned_two, tmp_path, nights):
    """Closed on night 1 until 2 h into night 2: night 2's evening does not re-plan into the closure."""
    executed = tmp_path / "executed.jsonl"
    p = open_pipeline(copy_state(planned_two, tmp_path), loop_config(executed), TWO)
    try:
        obs = the_plan(p)["observations"]
        write_executed(executed, executed_like(obs[:10]))
        closing = at(t(obs[9]["end"]), 60.0)
        reopening = at(nights[1][0], 7200.0)
        loop = ExecutedLoop(p.loop, p)
        assert loop.poll(closing).jobs == []
        acc = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure", now=closing.to_datetime())
        out = p.run_job(acc.job)
        assert out.decision == "replan" and out.plan_id, out
        closed = the_plan(p)
        assert min(t(o["start"]).unix for o in closed["observations"]) >= reopening.unix - 1e-3
        for minutes in (2, 30, 90):  # night 2's evening and the hours of the closure
            poll = loop.poll(at(nights[1][0], 60.0 * minutes))
            assert poll.jobs == [], poll.replans
        assert the_plan(p)["plan_id"] == closed["plan_id"]
        for r in p.store.plans(SUPEREVENT)[1:]:  # no revision after the closing observes inside it
            inside = [o for o in r["document"]["observations"] if closing.unix <= t(o["start"]).unix < reopening.unix]
            assert inside == [], (r["revision"], inside[:3])
    finally:
        p.store.close()


def test_a_re_plan_with_under_an_hour_left_ends_at_morning_twilight(planned_two, tmp_path, nights):
    executed = tmp_path / "executed.jsonl"
    write_executed(executed, [])
    p = open_pipeline(copy_state(planned_two, tmp_path), loop_config(executed), TWO)
    try:
        reopening = at(nights[0][1], -3500.0)
        acc = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure",
                               now=at(reopening, -3600.0).to_datetime())
        out = p.run_job(acc.job)
        assert out.decision == "replan" and out.plan_id, out  # the well-placed map has pairs in the last 58 min
        new = the_plan(p)
        assert t(new["end"]).unix <= nights[0][1].unix + 1.0  # its validity window ends by the morning twilight
        assert max(t(o["end"]).unix for o in new["observations"]) <= nights[0][1].unix + 1.0
        assert [j["status"] for j in replan_jobs(p.store, SUPEREVENT)] == ["done"]
    finally:
        p.store.close()


def test_without_a_source_a_closure_counts_nothing_done_while_closed(planned_two, tmp_path, nights, caplog):
    """(L14) revision 1 counts as done until the closing, not until the reopening."""
    p = open_pipeline(copy_state(planned_two, tmp_path), LoopConfig(), TWO)
    try:
        obs = the_plan(p)["observations"]
        closing = t(obs[9]["end"])
        reopening = at(closing, 7200.0)
        acc = p.replan_closure(SUPEREVENT, reopening.isot + "Z", "test:closure", now=closing.to_datetime())
        caplog.set_level(logging.INFO, logger="mushrooms.daemon.pipeline")
        out = p.run_job(acc.job)
        assert out.decision == "replan" and out.plan_id, out
        before = [o for o in obs if t(o["start"]).unix < closing.unix]
        closed = [o for o in obs if closing.unix <= t(o["start"]).unix < reopening.unix]
        assert closed  # revision 1 planned exposures during the closure
        counted = [int(m.group(1)) for r in caplog.records if (m := re.search(r" replan .* executed=(\d+)",
                                                                               r.getMessage()))]
        assert counted == [len(before)]
    finally:
        p.store.close()
