"""The loop in the running daemon (``mushrooms run``, a subprocess): the poll timer and ``trigger --closed-until``.

A real daemon on the mock broker (no notices on its topic) with ``[loop]``
reading a JSON-lines file every second and a directory outbox.  A notice is
handed to it with ``mushrooms trigger``; the plan's first 10 exposures are
written as executed; ``mushrooms trigger SUPEREVENT --closed-until`` reaches
the daemon through its trigger directory and SIGUSR1, and the re-plan comes
out as the event's revision 2, from the reopening.  Wall-clock times: the
checks are on the documents, not on durations.
"""

from __future__ import annotations

import time
from pathlib import Path

from astropy.time import Time, TimeDelta

from mushrooms.handlers.executed import write_jsonl
from mushrooms.scheduler_core.executed import ExecutedExposure, done_pairs

from daemon_helpers import Daemon, notice_path, write_config
from test_trigger import outbox_plans, trigger, wait_plans

CADENCE_S = 1800.0


def _t(iso: str) -> Time:
    return Time(iso.rstrip("Z"), scale="utc")


def test_the_running_daemon_polls_the_executed_file_and_replans_a_closure(broker, daemons, tmp_path: Path):
    topic = f"quiet-{time.time_ns()}"
    broker.ensure_topic(topic)
    executed = tmp_path / "executed.jsonl"
    cfg = write_config(tmp_path / "config.toml", topic, "unused", f"g-{time.time_ns()}",
                       extra=f'\n[loop]\nexecuted_source = "file:{executed}"\npoll_interval_s = 1.0\n')
    state, outbox = tmp_path / "state.sqlite", tmp_path / "outbox"
    common = ["--config", str(cfg), "--state", str(state), "--outbox", str(outbox)]
    d = Daemon(tmp_path, common + ["--bootstrap", broker.bootstrap])
    daemons.append(d)
    d.wait_log("event=executed_loop source=file:", timeout_s=180)
    d.wait_log("event=service_ready", timeout_s=180)

    r = trigger(tmp_path, str(notice_path("MS181101ab-preliminary.json")), *common)
    assert r.returncode == 0 and "handed to the daemon" in r.stdout, r.stdout + r.stderr
    (first,) = wait_plans(outbox, 1, d)
    obs = first["observations"]
    assert len(obs) >= 10, first["metrics"]
    ten = [ExecutedExposure(o["field_id"], o["filter"], _t(o["start"]), o["exposure_s"], 1.0, "processed")
           for o in obs[:10]]
    write_jsonl(ten, executed)
    d.wait_log("event=executed_read source=file:", timeout_s=60)
    d.wait_log("added=10", timeout_s=60)

    reopening = _t(obs[9]["end"]) + TimeDelta(7200.0, format="sec")
    r = trigger(tmp_path, "MS181101ab", "--closed-until", reopening.isot + "Z", *common)
    assert r.returncode == 0 and "replan" in r.stdout, r.stdout + r.stderr
    plans = wait_plans(outbox, 2, d)
    (second,) = [p for p in plans if p["plan_id"] != first["plan_id"]]
    assert (second["revision"], second["supersedes"]) == (2, first["plan_id"])
    assert min(_t(o["start"]).unix for o in second["observations"]) >= reopening.unix - 1e-3
    pairs = done_pairs(ten, ("g", "r"), cadence_s=CADENCE_S)
    assert not [o for o in second["observations"] if o["field_id"] in pairs.both]
    for field_id, visits in pairs.one.items():
        later = [o for o in second["observations"] if o["field_id"] == field_id
                 and o["filter"] != visits.filters[0]]
        assert all(_t(o["start"]).unix - visits.earliest.unix >= CADENCE_S for o in later)
    text = d.wait_log("replan superevent_id=MS181101ab origin=trigger:")
    assert "Traceback" not in text
    assert d.stop() == 0
    assert len(outbox_plans(outbox)) == 2
