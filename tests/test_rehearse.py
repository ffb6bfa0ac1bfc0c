"""``mushrooms rehearse``: a loopback broker, the real service, a live notice, until the plan is final.

Real parts throughout: librdkafka's mock cluster on 127.0.0.1, ``mushrooms run``
in a process of its own, the greedy scheduler on a real sky map, a SQLite state
file.  Plus the live copy of a notice and the words the rehearsal prints.
"""

from __future__ import annotations

import base64
import datetime as dt
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mushrooms.bundled import demo_notice_path
from mushrooms.scheduler_core.errors import InputError
from mushrooms.tool.live_notice import MAX_LEAD_S, live_copy
from mushrooms.tool.rehearse_watch import log_words, parse_log_line

NOTICES = Path(__file__).resolve().parent / "data" / "notices" / "json"
ROOT = Path(__file__).resolve().parents[1]

GREEDY = """
[scheduler]
solver = "greedy"
nside = 64

[daemon]
heartbeat_s = 2
"""


def rehearse(tmp_path: Path, *args: str, env: dict[str, str] | None = None, timeout: float = 600
             ) -> subprocess.CompletedProcess:
    cfg = tmp_path / "config.toml"
    cfg.write_text(GREEDY)
    e = {k: v for k, v in os.environ.items() if not k.startswith("MUSHROOMS_SUBMIT")}
    e["PYTHONPATH"] = str(ROOT)  # this checkout's mushrooms, for the rehearsal and for its service
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", "rehearse", "--config", str(cfg), *args],
                          capture_output=True, text=True, env=e, cwd=tmp_path, timeout=timeout)


def test_a_rehearsal_plans_the_bundled_notice_until_final_and_stops_the_service_cleanly(tmp_path):
    out = tmp_path / "rehearsal"
    r = rehearse(tmp_path, "--out", str(out), "--dry-run", "--set", 'submit.target="kowalski"',
                 "--set", 'submit.url="http://127.0.0.1:9"')
    assert r.returncode == 0, r.stdout + r.stderr
    said = r.stdout
    assert "loopback broker on 127.0.0.1:" in said
    assert "as a DRY RUN" in said
    assert "notice MS260605l PRELIMINARY received: plan" in said
    assert "revision 1 of MS260605l published" in said and "; final)" in said  # greedy: revision 1 is final
    assert "submission (dry run) of" in said  # the rehearsal waited for the submission's outcome
    assert "Planned    " in said and "First      " in said  # the plan's text summary
    assert "service stopped cleanly (exit 0)" in said
    last = said.rstrip().splitlines()[-1]
    assert "rehearsal passed: MS260605l revision 1 final" in last and last.endswith(f"; everything in {out}")
    plans = [json.loads(p.read_text()) for p in (out / "outbox").glob("*.json")]
    plan = next(p for p in plans if p.get("type") == "plan")
    assert plan["final"] is True and plan["observations"]
    # the notice went out live: its merger is minutes old, not the archived June one
    merger = dt.datetime.fromisoformat(plan["event"]["event_time"].replace("Z", "+00:00"))
    if merger.tzinfo is None:
        merger = merger.replace(tzinfo=dt.timezone.utc)
    assert abs((dt.datetime.now(dt.timezone.utc) - merger).total_seconds()) < 3600
    assert (out / "outbox" / f"{plan['plan_id']}.txt").is_file()
    log = (out / "service.log").read_text()
    assert "event=service_stopped" in log and "event=submission_dry_run" in log
    assert not (out / "mushrooms.pid").exists()  # the service released its pid file: a clean stop


def test_a_rehearsal_whose_service_cannot_start_fails_with_one_line(tmp_path):
    # [submit] to Kowalski, not a dry run, and no token: the service refuses to start
    r = rehearse(tmp_path, "--set", 'submit.target="kowalski"', "--set", 'submit.url="http://127.0.0.1:9"')
    assert r.returncode == 1
    errors = [line for line in r.stderr.splitlines() if line.startswith("mushrooms rehearse:")]
    assert len(errors) == 1 and "submission token not found" in errors[0], r.stderr
    assert "gave up" not in errors[0]


def test_a_rehearsal_of_a_notice_the_policy_does_not_plan_says_why(tmp_path):
    r = rehearse(tmp_path, str(NOTICES / "MS181101ab-retraction.json"))
    assert r.returncode == 1
    assert "did not plan the notice" in r.stderr, r.stdout + r.stderr
    assert "service stopped cleanly (exit 0)" in r.stdout  # stopped all the same


def test_a_rehearsal_refuses_bad_input_before_starting_anything(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    r = rehearse(tmp_path, str(bad))
    assert r.returncode == 2 and "not a JSON notice" in r.stderr
    r = rehearse(tmp_path, "--set", "scheduler.nside=3")
    assert r.returncode == 2 and "nside" in r.stderr
    assert "loopback broker" not in r.stdout


def test_a_live_copy_moves_every_clock_of_the_notice_to_now():
    from astropy.io import fits

    raw = Path(demo_notice_path()).read_bytes()
    old = json.loads(raw)
    now = dt.datetime(2026, 12, 2, 3, 4, 5, tzinfo=dt.timezone.utc)
    copy, times = live_copy(raw, now=now)
    doc = json.loads(copy)
    assert doc["time_created"] == "2026-12-02T03:04:05.000Z" == times["created"]
    lead = (dt.datetime.fromisoformat(old["time_created"].replace("Z", "+00:00"))
            - dt.datetime.fromisoformat(old["event"]["time"].replace("Z", "+00:00"))).total_seconds()
    merger = dt.datetime.fromisoformat(doc["event"]["time"].replace("Z", "+00:00"))
    assert (now - merger).total_seconds() == pytest.approx(lead, abs=0.001)
    with fits.open(io.BytesIO(base64.b64decode(doc["event"]["skymap"]))) as hdus:
        assert hdus[1].header["DATE-OBS"].startswith(merger.strftime("%Y-%m-%dT%H:%M:%S"))
    assert doc["superevent_id"] == old["superevent_id"] and doc["event"]["far"] == old["event"]["far"]


def test_a_late_update_keeps_at_most_ten_minutes_between_merger_and_notice():
    raw = (NOTICES / "MS181101ab-update.json").read_bytes()
    now = dt.datetime(2026, 12, 2, tzinfo=dt.timezone.utc)
    doc = json.loads(live_copy(raw, now=now)[0])
    merger = dt.datetime.fromisoformat(doc["event"]["time"].replace("Z", "+00:00"))
    assert 0 <= (now - merger).total_seconds() <= MAX_LEAD_S


@pytest.mark.parametrize("raw, why", [(b"\xff\xfe", "not a JSON notice"), (b"[1, 2]", "no superevent_id"),
                                      (b'{"superevent_id": "S1", "time_created": "yesterday"}', "time_created")])
def test_a_live_copy_refuses_what_is_not_a_notice(raw, why):
    with pytest.raises(InputError, match=why):
        live_copy(raw)


def test_the_service_log_is_told_in_words_and_every_warning_is_told():
    line = parse_log_line("2026-12-05 23:10:00,123 INFO mushrooms.daemon.service: event=notice origin=kafka:x "
                          "bytes=10 superevent_id=MS1 alert_type=PRELIMINARY decision=ignore reason='too old: 3 d' "
                          "jobs_started=0 store_s=0.01")
    assert line is not None and line.event == "notice" and line.fields["reason"] == "too old: 3 d"
    assert log_words(line) == "notice MS1 PRELIMINARY received: ignore (too old: 3 d)"
    quiet = parse_log_line("2026-12-05 23:10:00,123 INFO mushrooms.daemon.service: event=heartbeat uptime_s=3")
    assert log_words(quiet) is None
    odd = parse_log_line("2026-12-05 23:10:00,123 WARNING mushrooms.daemon.x: something   odd happened")
    assert log_words(odd) == "WARNING: something odd happened"
    assert parse_log_line("Traceback (most recent call last):") is None


def test_trigger_and_status_show_the_summary_of_the_revision_they_made(tmp_path):
    cfg = tmp_path / "config.toml"
    cfg.write_text(GREEDY + "\n[policy]\nmax_notice_age_s = 0\nmax_event_age_s = 0\n")
    state, outbox = tmp_path / "state.sqlite", tmp_path / "outbox"
    run = lambda *a: subprocess.run([sys.executable, "-m", "mushrooms.cli", *a, "--config", str(cfg)],  # noqa: E731
                                    capture_output=True, text=True, cwd=tmp_path, timeout=600)
    r = run("trigger", demo_notice_path(), "--allow-mock", "--state", str(state), "--outbox", str(outbox))
    assert r.returncode == 0, r.stdout + r.stderr
    plan = next(json.loads(p.read_text()) for p in outbox.glob("*.json"))
    assert f"Revision   {plan['plan_id']} revision 1 (final)" in r.stdout
    assert "Planned    " in r.stdout and "Distance   " in r.stdout
    s = run("status", "--state", str(state))
    assert s.returncode == 0, s.stdout + s.stderr
    assert f"  in force: {plan['plan_id']}: {plan['metrics']['n_fields']} fields in g and r" in s.stdout
    assert f"    Revision   {plan['plan_id']} revision 1 (final)" in s.stdout
    doc = json.loads(run("status", "--state", str(state), "--json").stdout)
    assert doc["events"][0]["current"]["plan_id"] == plan["plan_id"]
    assert doc["events"][0]["current"]["summary"].startswith(f"Revision   {plan['plan_id']}")


def test_a_rehearsal_killed_with_sigkill_takes_its_service_down(tmp_path):
    import re
    import signal
    import time

    cfg = tmp_path / "config.toml"
    cfg.write_text(GREEDY)
    out, said = tmp_path / "rehearsal", tmp_path / "said.txt"
    with open(said, "wb") as fh:
        proc = subprocess.Popen([sys.executable, "-m", "mushrooms.cli", "rehearse", "--config", str(cfg), "--out",
                                 str(out)], stdout=fh, stderr=subprocess.STDOUT, cwd=tmp_path)
    try:
        end = time.monotonic() + 300
        while "service ready after" not in said.read_text():  # killed while it waits for the service to consume
            assert proc.poll() is None and time.monotonic() < end, said.read_text()
            time.sleep(0.1)
        service = int(re.search(r"service started \(pid (\d+)\)", said.read_text()).group(1))
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        assert "stopping the service" not in said.read_text()  # the rehearsal died before it could stop it
        end = time.monotonic() + 120
        while "event=service_stopped" not in (out / "service.log").read_text():
            assert time.monotonic() < end, (out / "service.log").read_text()[-3000:]
            time.sleep(0.2)
        end = time.monotonic() + 30
        while os.path.exists(f"/proc/{service}") and "zombie" not in _state(service):
            assert time.monotonic() < end, "the service outlived its rehearsal"
            time.sleep(0.2)
    finally:
        if proc.poll() is None:
            proc.kill()


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/status").read_text().split("State:")[1].split("\n")[0].lower()
    except (OSError, IndexError):
        return "zombie"


def test_a_rehearsal_tells_the_webhook_and_fails_when_the_submission_target_is_down(tmp_path, httpserver):
    httpserver.expect_request("/hook", method="POST").respond_with_data("ok")
    r = rehearse(tmp_path, "--set", "notify.target=json", "--set", "submit.target=kowalski",
                 "--set", "submit.url=http://127.0.0.1:9", "--set", "submit.timeout_s=2",
                 env={"MUSHROOMS_NOTIFY_URL": httpserver.url_for("/hook"), "MUSHROOMS_SUBMIT_TOKEN": "tok-rehearse"})
    assert r.returncode == 1, r.stdout + r.stderr
    assert "REAL requests will be sent" in r.stdout and "webhook told: plan_published (HTTP 200)" in r.stdout
    assert "Planned    " in r.stdout  # the plan is final and summarised all the same
    errors = [line for line in r.stderr.splitlines() if line.startswith("mushrooms rehearse:")]
    assert len(errors) == 1 and "the plan is final, but submission of" in errors[0]
    assert "did not reach the queue" in errors[0] and "Connection refused" in errors[0]
    told = [json.loads(req.get_data())["event"] for req, _ in httpserver.log]
    assert told[0] == "plan_published" and "submission_failing" in told
    assert "tok-rehearse" not in r.stdout + r.stderr and "/hook" not in r.stdout


def test_a_rehearsal_refuses_a_webhook_url_that_cannot_be_parsed_and_leaves_no_secret(tmp_path):
    secret = "s3cr3t-rehearse-hook"
    out = tmp_path / "rehearsal"
    r = rehearse(tmp_path, "--out", str(out), "--dry-run", "--set", "notify.target=slack",
                 env={"MUSHROOMS_NOTIFY_URL": f"hooks.slack.com/services/T0/B0/{secret}"})
    assert r.returncode == 2, r.stdout + r.stderr  # today: 0, the notifier dead and the URL in service.log
    errors = [line for line in r.stderr.splitlines() if line.startswith("mushrooms rehearse:")]
    assert len(errors) == 1 and "webhook URL" in errors[0], r.stderr
    left = [p.read_bytes() for p in out.rglob("*") if p.is_file()] if out.exists() else []
    assert not any(secret.encode() in data for data in left)
    assert secret not in r.stdout + r.stderr and "Traceback" not in r.stdout + r.stderr


def test_a_timeout_that_is_not_a_positive_number_of_seconds_is_refused_before_anything_starts(tmp_path):
    # nan and inf were accepted: a rehearsal whose plan never became final never ended (the subprocess
    # timeout is a hang guard); 0 and negative numbers were refused already
    for timeout in ("nan", "inf", "1e300", "-inf", "-5", "0"):
        r = rehearse(tmp_path, f"--timeout={timeout}", timeout=120)
        assert r.returncode == 2, timeout + ": " + r.stdout[-2000:] + r.stderr[-2000:]
        errors = [line for line in r.stderr.splitlines() if "error" in line]
        assert len(errors) == 1 and "--timeout must be a number of seconds in (0, 86400]" in errors[0], r.stderr
        assert "loopback broker" not in r.stdout and "service started" not in r.stdout


def test_a_first_stage_job_failure_ends_the_rehearsal_at_once_with_one_line(tmp_path):
    # a real failure of the job's first stage: the notice's sky map is larger than [policy] allows, so the
    # job logs `decision=rejected` (no `event=job_failed`); the rehearsal once waited out its --timeout
    r = rehearse(tmp_path, "--set", "policy.max_skymap_bytes=2880", "--timeout", "400", timeout=600)
    assert r.returncode == 1, r.stdout + r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("mushrooms rehearse:")]
    assert len(errors) == 1, r.stderr
    assert "planning MS260605l failed (rejected)" in errors[0] and "2880-byte limit" in errors[0], errors
    assert "gave up" not in errors[0] and "--timeout" not in errors[0]
    assert "service stopped cleanly (exit 0)" in r.stdout  # stopped all the same


#: What the service logs when a job's first stage fails (``mushrooms run`` of today, ``[scheduler] slew = 1``).
JOB_FAILED = ("2026-12-06 14:08:51,956 INFO mushrooms.daemon.jobs: event=job_done superevent_id=MS260605l job=1 "
              "action=failed decision=failed reason=\"internal error: AttributeError: 'int' object has no attribute "
              "'ha_accel_deg_s2'\" latency_s=0.081 run_s=0.068")
WARM_FAILED = ("2026-12-06 14:08:47,001 ERROR mushrooms.daemon: event=warm_up_plan_failed "
               "error=\"SkyMapError: broken-demo-map.fits: not a FITS file\" reason='the service is not ready'")


@pytest.mark.parametrize("text, said", [
    (JOB_FAILED, "planning MS260605l failed (failed): internal error: AttributeError: 'int' object has no "
                 "attribute 'ha_accel_deg_s2'"),
    (WARM_FAILED, "the service is not ready: its warm-up plan failed: SkyMapError: broken-demo-map.fits: not a "
                  "FITS file"),
])
def test_the_rehearsal_fails_on_the_lines_a_failing_job_and_a_failing_warm_up_write(tmp_path, text, said):
    from mushrooms.tool.rehearsal import Rehearsal, RehearsalFailed

    watch = Rehearsal([], tmp_path, 0.0, 60.0, None)
    with pytest.raises(RehearsalFailed) as failed:
        watch._judge(parse_log_line(text))
    assert str(failed.value) == said


def test_a_rehearsal_in_a_temporary_directory_removes_it_when_it_passes_and_keeps_it_when_it_fails(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r = rehearse(tmp_path, env={"TMPDIR": str(tmp)})
    assert r.returncode == 0, r.stdout + r.stderr
    assert list(tmp.glob("mushrooms-rehearse-*")) == []
    assert "give --out DIR to keep" in r.stdout
    r = rehearse(tmp_path, str(NOTICES / "MS181101ab-retraction.json"), env={"TMPDIR": str(tmp)})
    assert r.returncode == 1
    [kept] = tmp.glob("mushrooms-rehearse-*")
    assert (kept / "service.log").is_file() and str(kept / "service.log") in r.stdout + r.stderr
