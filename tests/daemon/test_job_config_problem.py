"""A configuration problem met during a job is the configuration's failure, not the notice's (issue 52 follow-up).

``[scheduler] detection_lightcurve`` may name a file; it is parsed at load
(``tool/config.py``), but read again by every job (the plan's expected
detections).  Edited or removed while the service runs, every job failed with
the light curve's error recorded as decision ``rejected``: the notice was
blamed, the event kept the map's hash (so the same notice again was a
``duplicate`` and ``mushrooms trigger`` exited 2, "bad input"), and nothing
said the configuration was at fault.  Here, with the real pipeline, store and
directory sink (``mushrooms trigger`` without a daemon): the job fails as
``failed`` with a reason that names the configuration, and once the file is
repaired the same notice is planned.
"""

from __future__ import annotations

import json
from pathlib import Path

from daemon_helpers import notice_path
from test_trigger import RecordingConsole

from mushrooms.daemon.intake.trigger import classify
from mushrooms.daemon.intake.trigger_command import run_trigger
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.state.views import connect_readonly
from mushrooms.tool.config import load_config
from mushrooms.tool.overrides import override_config

LIGHT_CURVE = "# t[days] g r\n0.1 -15.0 -15.0\n1.0 -15.5 -15.5\n3.0 -14.0 -14.0\n"


def _trigger(config, paths, notice: Path) -> tuple[int, list[tuple[str, str]]]:
    console = RecordingConsole()
    kind, payload = classify(str(notice))
    return run_trigger(str(notice), kind, payload, config, paths, console=console), console.said


def test_a_light_curve_broken_after_load_fails_the_job_as_the_configurations_and_a_replan_follows_the_fix(tmp_path):
    curve = tmp_path / "kilonova.txt"
    curve.write_text(LIGHT_CURVE)
    cfg = tmp_path / "config.toml"
    cfg.write_text(f'[scheduler]\nsolver = "greedy"\nnside = 64\ndetection_lightcurve = "{curve}"\n\n'
                   '[policy]\nallow_mock = true\nmax_notice_age_s = 0\nmax_event_age_s = 0\n')
    config = override_config(load_config(str(cfg)), outbox=str(tmp_path / "outbox"),
                             state=str(tmp_path / "state.sqlite"))  # loads: the file parses now
    paths = resolve_paths(config.daemon)
    notice = notice_path("MS181101ab-preliminary.json")

    curve.write_text("this is no light curve\n")  # edited while the service runs
    status, said = _trigger(config, paths, notice)
    print(said)
    conn = connect_readonly(paths.state)
    (job,) = conn.execute("SELECT status, reason FROM jobs").fetchall()
    conn.close()
    assert status == 1, said  # 1: a job failed; 2 said "bad input" of a good notice
    assert job["status"] == "failed" and "configuration" in job["reason"] and str(curve) in job["reason"], dict(job)
    assert any(kind == "error" and "job failed: configuration" in text for kind, text in said), said

    curve.write_text(LIGHT_CURVE)  # repaired: the same notice is planned again, not a duplicate
    status, said = _trigger(config, paths, notice)
    print(said)
    assert status == 0, said
    plans = [json.loads(p.read_text()) for p in (tmp_path / "outbox").glob("*.json")]
    assert [p["event"]["superevent_id"] for p in plans if p.get("type") == "plan"] == ["MS181101ab"], said
