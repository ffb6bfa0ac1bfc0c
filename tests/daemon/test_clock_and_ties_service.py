"""Through ``mushrooms run``: one merger clock, and ties in expected detections go to coverage.

A real daemon process on the mock broker with the shipped ``[scheduler]``
defaults (hybrid, objective detection, nside 256, 14 s; ``[daemon]
supersede_min_gain`` 0.005) gets two live copies of MS230425l's preliminary
notice (``time_created`` = ``event.time`` = now, GW map only):

* ``stale``: the map as archived, its ``DATE-OBS`` 2023-04-25. The plans'
  kilonova clock is the notice's (``event.merger_time_source = notice``, one
  warning with both times), so the plans expect detections (on the map's
  clock they would expect 0), and the optimiser's plan supersedes revision 1
  exactly when the rule (R1-R3, ``docs/design/detection.md`` section 5)
  says so.
* ``distant``: the same event 50 times farther (~5 Gpc): both plans expect ~0
  detections, a tie (R3), so the final plan is the one with more coverage.

Which outcome the optimiser reaches depends on the sky at the time of the
run (the horizon starts at receipt); the rule applied to the published
numbers does not. ``benchmarks/loop/clock_and_ties_daemon.py`` prints the numbers
(``benchmarks/loop/clock_and_ties_daemon.py``).
"""

from __future__ import annotations

import time
from datetime import datetime, timezone
from pathlib import Path

import pytest
from daemon_helpers import BROKER_SECTIONS, Daemon, final_numbers, live_copy

from mushrooms.scheduler_core.preference import is_preferred

NOTICE = "MS230425l-preliminary.json"
MARGIN = 0.005  # [daemon] supersede_min_gain (default)
FLOOR = 0.02  # [scheduler] detection_max_coverage_loss (default)

CONFIG = """
[policy]
allow_mock = true

[daemon]
heartbeat_s = 2
job_deadline_s = 600

"""
CONFIG += BROKER_SECTIONS


def _now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


@pytest.mark.slow  # a scenario: the shipped hybrid (nside 256, 14 s) on two live events, about 25 s
def test_live_notice_with_a_stale_map_and_a_distant_event_through_the_daemon(broker, daemons, tmp_path: Path) -> None:
    tag = time.time_ns()
    topic, out, group = f"gwalert-{tag}", f"plans-{tag}", f"mushrooms-{tag}"
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    cfg = tmp_path / "config.toml"
    cfg.write_text(CONFIG.format(topic=topic, out_topic=out, group=group))
    sent = {}
    for sid, farther in (("MS230425l", None), ("MS230425z", 50.0)):
        sent[sid] = _now()
        broker.produce(topic, live_copy(NOTICE, sid, sent[sid], farther), key=sid.encode())
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(tmp_path / "s.sqlite")])
    daemons.append(d)
    reader = broker.reader(out, f"reader-{tag}")

    def finished(ms: list[dict]) -> bool:
        done = {(m.get("event") or {}).get("superevent_id") or m.get("superevent_id") for m in ms if m.get("final")}
        return set(sent) <= done

    try:
        msgs = reader.wait_for(finished, 300, alive=d.alive)
    finally:
        reader.close()
    assert d.stop() == 0
    log = d.text()

    for sid, now in sent.items():
        n = final_numbers(msgs, sid)
        for doc in (n["r1"], n["r2"]):
            if doc is not None:  # the kilonova clock is the notice's, on every revision
                assert doc["event"]["event_time"] == now and doc["event"]["merger_time_source"] == "notice"
        assert n["e2"] is not None and n["c2"] is not None, n["reason"]
        # the daemon decided by the one rule (R1-R3) on what it published
        should = is_preferred(n["c2"], n["e2"], n["c1"], n["e1"], MARGIN, "detection",
                              coverage_floor=(1 - FLOOR) * n["c1"])
        assert (n["won"] == 2) == should, (sid, n)
        warned = [x for x in log.splitlines() if f"{sid}: merger time: the notice says {now}" in x]
        assert len(warned) == 1 and "2023-04-25T11:42:28" in warned[0]  # once per notice, both values

    stale, distant = final_numbers(msgs, "MS230425l"), final_numbers(msgs, "MS230425z")
    assert stale["e1"] > 0.05  # on the map's 2023 clock every light curve is dark: 0
    assert distant["e1"] < 1e-4 and distant["e2"] < 1e-4  # a tie at ~0 (R3) ...
    final_cov = distant["c2"] if distant["won"] == 2 else distant["c1"]
    assert final_cov >= max(distant["c1"], distant["c2"]) - MARGIN  # ... so the final plan has the better coverage
    if stale["e2"] - stale["e1"] >= MARGIN and stale["c2"] >= (1 - FLOOR) * stale["c1"]:
        assert stale["won"] == 2 and stale["r2"]["supersedes"] == stale["r1"]["plan_id"]  # (R2)
