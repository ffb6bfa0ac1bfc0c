"""The other telescopes' SkyPortal parts are sent (``[submit_parts]``, issue 53 item 4).

A WINTER part (``queue = "skyportal"``) becomes one observation plan request,
``POST /api/observation_plan/manual`` with the telescope's allocation; the
same trust rules as the ZTF submitter: off by default; nothing lost (a part
not sent stays pending and is sent after a restart); a kill -9 between the
POST and its record is recognised by the request's name (no second import);
5xx, 3xx, a huge or wrong answer and a drip are handled within the deadline;
the token never in the state file, the outbox or the log; a retraction
DELETEs the request, a newer map's part replaces it once that one is sent.
Against a SkyPortal contract server on loopback (pytest-httpserver).
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import signal
from pathlib import Path

import pytest

from part_requests_setup import send_killed_at_the_post, SID, TOKEN, PartsSkyPortal, parts_state, plan_start, rows, sender



@pytest.fixture
def skyportal(loopback):
    return PartsSkyPortal(loopback)


def _step(state: Path, url: str, after: dt.timedelta = dt.timedelta(0), **settings) -> int:
    """One pass of a freshly opened sender (a restart), at the plan's start (or ``after`` it)."""
    s, store = sender(state, url, **settings)
    try:
        return s.step(now=plan_start() + after)
    finally:
        store.close()


def test_off_by_default_nothing_is_sent():
    from mushrooms.daemon.submission.parts_thread import open_part_sender, parts_token
    from mushrooms.tool.config import Config

    config = Config()
    assert config.submit_parts.enabled is False and dict(config.submit_parts.allocations) == {}
    assert open_part_sender(config, store=None, token=None) is None and parts_token(config) is None


def test_a_winter_part_is_sent_once_with_its_allocation(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    (post,) = skyportal.posts()
    assert post["authorization"] == f"token {TOKEN}" and post["status"] == 200
    (body,) = skyportal.plans.values()
    request = json.loads(next((tmp_path / "outbox").rglob("skyportal_request.json")).read_text())
    assert body["allocation_id"] == 7 and body["plan_name"] == body["payload"]["queue_name"] == request["plan_name"]
    assert body["plan_name"].startswith(f"winter_{SID}_") and body["dateobs"] == "2018-11-01T22:22:46.654"
    planned = body["observation_plans"][0]["planned_observations"]
    assert len(planned) == 138 and {o["filt"] for o in planned} == {"2massj"}  # SkyPortal's name of WINTER's J
    assert all(o["exposure_time"] == 300.0 and o["weight"] >= 0 for o in planned)
    (row,) = rows(state)
    assert row["state"] == "sent" and row["remote_id"] == "1" and row["tried"] == 1
    assert _step(state, skyportal.url) == 0 and len(skyportal.posts()) == 1  # sent once


def test_a_5xx_keeps_it_pending_and_a_restart_sends_it_once(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    skyportal.faults["POST"] = ["503"]
    assert _step(state, skyportal.url) == 1
    (row,) = rows(state)
    assert row["state"] == "pending" and row["tried"] == 1 and row["http_status"] == 503
    assert _step(state, skyportal.url) == 0  # the restart: looked up by name (not there), POSTed again
    (row,) = rows(state)
    assert row["state"] == "sent" and len(skyportal.plans) == 1 and row["attempts"] == 2


def test_a_kill9_between_post_and_record_is_recognised_not_sent_twice(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    code, out, err = send_killed_at_the_post(state, skyportal)
    assert code == -signal.SIGKILL and b"not killed" not in out, err[-2000:]
    (row,) = rows(state)
    assert row["state"] == "pending" and row["tried"] == 1 and row["remote_id"] is None  # the answer never recorded
    assert _step(state, skyportal.url) == 0
    (row,) = rows(state)
    assert row["state"] == "sent" and row["remote_id"] == "1" and "found in SkyPortal" in row["reason"]
    assert len(skyportal.posts()) == 1 and list(skyportal.plans) == [1]  # imported once


@pytest.mark.parametrize("fault", ["500", "drip", "huge"])
def test_hostile_answers_within_the_deadline_and_never_a_second_import(tmp_path, skyportal, fault, caplog):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    skyportal.hang_s, skyportal.drip_s = 30.0, 0.5  # a drip would last 30 s; the deadline is 2 s
    if fault == "huge":
        skyportal.huge_next = True
    else:
        skyportal.faults["POST"] = [fault]
    with caplog.at_level(logging.DEBUG):
        assert _step(state, skyportal.url) == 1  # waiting: the answer was not SkyPortal's
        (row,) = rows(state)
        assert row["state"] == "pending" and row["tried"] == 1
        assert _step(state, skyportal.url) == 0
    (row,) = rows(state)
    assert row["state"] == "sent" and len(skyportal.plans) == 1  # imported once
    if fault == "huge":  # stored, then answered with 5 MB: found by name, not POSTed again
        assert len(skyportal.posts()) == 1 and "found in SkyPortal" in row["reason"]
    else:  # the 500 and the drip stored nothing: looked up, not found, POSTed again
        assert len(skyportal.posts()) == 2 and row["attempts"] == 2
    _no_token(tmp_path, caplog)


def test_a_redirect_is_a_refusal_never_followed(tmp_path, skyportal, caplog):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    skyportal.faults["POST"] = ["302"]
    with caplog.at_level(logging.DEBUG):
        assert _step(state, skyportal.url) == 0
    (row,) = rows(state)
    assert row["state"] == "rejected" and "302" in row["reason"]
    assert _step(state, skyportal.url) == 0 and len(skyportal.posts()) == 1  # never retried
    _no_token(tmp_path, caplog)


def test_a_refused_post_is_rejected_and_the_request_skyportal_kept_is_deleted(tmp_path, loopback):
    skyportal = PartsSkyPortal(loopback, filters=("J",))  # an instance whose WINTER names J otherwise
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    (row,) = rows(state)
    assert row["state"] == "rejected" and "not in instrument's filter list" in row["reason"]
    assert "had kept request 1 of that name: deleted" in row["reason"] and skyportal.plans == {}


def test_a_retraction_deletes_the_request(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0 and len(skyportal.plans) == 1
    import sqlite3

    with sqlite3.connect(state) as c:  # the retraction: the event retracted (parts withdrawn once published)
        c.execute("UPDATE events SET retracted=1")
    assert _step(state, skyportal.url) == 0
    (row,) = rows(state)
    assert row["state"] == "deleted" and skyportal.plans == {}
    assert [(e["method"], e["path"]) for e in skyportal.log if e["method"] == "DELETE"] == [
        ("DELETE", "/api/observation_plan/1")]


def test_a_newer_part_replaces_the_old_request_only_once_it_is_sent(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "superseded"), (2, "UPDATE", "exported")])
    import sqlite3

    with sqlite3.connect(state) as c:
        c.execute("UPDATE telescope_parts SET state='exported' WHERE job_id=1")
    assert _step(state, skyportal.url) == 0  # job 1's part standing alone: sent ... and so job 2's
    with sqlite3.connect(state) as c:
        c.execute("DELETE FROM part_requests WHERE job_id=2")
        c.execute("UPDATE telescope_parts SET state='superseded' WHERE job_id=1")
    skyportal.plans.pop(2)
    skyportal.faults["POST"] = ["503"]
    assert _step(state, skyportal.url) == 1  # the newer part waits: the old request stays
    assert [r["state"] for r in rows(state)] == ["sent", "pending"] and list(skyportal.plans) == [1]
    assert _step(state, skyportal.url) == 0
    assert [r["state"] for r in rows(state)] == ["replaced", "sent"] and list(skyportal.plans) == [3]


def test_a_delete_skyportal_refuses_is_failed_with_remove_by_hand(tmp_path, skyportal):
    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    skyportal.undeletable = True
    import sqlite3

    with sqlite3.connect(state) as c:
        c.execute("UPDATE events SET retracted=1")
    assert _step(state, skyportal.url) == 0
    (row,) = rows(state)
    assert row["state"] == "failed" and "Cannot delete observation plans on this instrument" in row["reason"]
    assert "remove it by hand" in row["reason"] and list(skyportal.plans) == [1]


def test_a_delete_that_keeps_failing_waits_then_fails_at_the_window_end(tmp_path, skyportal):
    import sqlite3

    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    with sqlite3.connect(state) as c:
        c.execute("UPDATE events SET retracted=1")
    skyportal.faults["DELETE"] = ["500", "500"]
    assert _step(state, skyportal.url) == 1 and rows(state)[0]["state"] == "sent"  # retried while the window lasts
    assert _step(state, skyportal.url, after=dt.timedelta(days=2)) == 0
    (row,) = rows(state)
    assert row["state"] == "failed" and "before its window ended" in row["reason"] and "by hand" in row["reason"]


@pytest.mark.parametrize("case", ["no allocation", "earlywarning", "window ended", "dry run"])
def test_what_is_not_sent_says_why_and_sends_nothing(tmp_path, skyportal, case):

    alert = "EARLYWARNING" if case == "earlywarning" else "PRELIMINARY"
    state = parts_state(tmp_path, [(1, alert, "exported")])
    s, store = sender(state, skyportal.url, **({"allocations": {"ls4": 3}} if case == "no allocation" else {}),
                      **({"dry_run": True} if case == "dry run" else {}))
    try:
        s.step(now=plan_start() + dt.timedelta(days=2 if case == "window ended" else 0))
    finally:
        store.close()
    (row,) = rows(state)
    expected = {"no allocation": ("failed", "no SkyPortal allocation for winter"),
                "earlywarning": ("skipped", "EARLYWARNING is not in [submit_parts] alert_types"),
                "window ended": ("failed", "validity window ended"), "dry run": ("skipped", "dry run")}[case]
    assert (row["state"], expected[1] in row["reason"]) == (expected[0], True) and skyportal.log == []


def test_settings_refuse_a_url_with_credentials_and_a_missing_token_is_one_line():
    from mushrooms.daemon.credentials import CredentialsError, load_parts_token
    from mushrooms.daemon.submission.parts_settings import PartSubmitConfig

    with pytest.raises(ValueError, match="url"):
        PartSubmitConfig.from_mapping({"enabled": True, "url": "https://user:pw@skyportal.example"})
    with pytest.raises(ValueError, match="allocations"):
        PartSubmitConfig.from_mapping({"allocations": {"winter": "seven"}})
    with pytest.raises(CredentialsError, match="MUSHROOMS_SKYPORTAL_TOKEN"):
        load_parts_token({})


def _no_token(tmp_path: Path, caplog) -> None:
    """The token is in no file under ``tmp_path`` (state, outbox) and in no log line."""
    for path in tmp_path.rglob("*"):
        if path.is_file():
            assert TOKEN.encode() not in path.read_bytes(), path
    assert TOKEN not in caplog.text


@pytest.mark.slow
def test_the_service_plans_a_winter_part_and_it_is_sent(tmp_path, skyportal):
    """End to end: the daemon's pipeline (``telescopes = ["ztf", "winter"]``) writes the part, the sender sends it."""

    from daemon_helpers import notice_bytes
    from telescope_parts_setup import open_parts_pipeline, parts_config

    pipeline, close = open_parts_pipeline(parts_config(tmp_path, ["ztf", "winter"]))
    try:
        out = pipeline.handle(notice_bytes(f"{SID}-preliminary.json"), "test:parts")
    finally:
        close()
    assert out.decision == "plan"
    state = tmp_path / "state.sqlite"
    s, store = sender(state, skyportal.url)
    try:
        assert s.step(now=dt.datetime.now(dt.timezone.utc)) == 0
    finally:
        store.close()
    (row,) = rows(state)
    assert row["state"] == "sent" and row["telescope"] == "winter" and len(skyportal.plans) == 1
    (body,) = skyportal.plans.values()
    request = json.loads(next((tmp_path / "outbox").rglob("skyportal_request.json")).read_text())
    assert body["plan_name"] == request["plan_name"] and body["allocation_id"] == 7
    assert len(body["observation_plans"][0]["planned_observations"]) == len(request["planned_observations"]) > 0


def test_the_daemons_thread_sends_after_a_kick_and_retries_with_back_off(tmp_path, skyportal):
    """``open_part_sender`` (the service's wiring): a kick sends; a 503 is retried by the drain itself."""
    import time

    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.submission.parts_settings import PartSubmitConfig
    from mushrooms.daemon.submission.parts_thread import open_part_sender

    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    config = type("C", (), {"submit_parts": PartSubmitConfig.from_mapping({
        "enabled": True, "url": skyportal.url, "allocations": {"winter": 7}, "timeout_s": 2.0,
        "retry_initial_s": 0.05, "retry_max_s": 0.2})})()
    skyportal.faults["POST"] = ["503"]
    store = Store(state)
    sender_, drain = open_part_sender(config, store, TOKEN, clock=plan_start)
    try:
        drain.kick()
        end = time.monotonic() + 60  # a hang guard only
        while not (rows(state) and rows(state)[0]["state"] == "sent") and time.monotonic() < end:
            time.sleep(0.05)
    finally:
        drain.close(timeout_s=5.0)
        store.close()
    (row,) = rows(state)
    assert row["state"] == "sent" and row["attempts"] == 2 and drain.failures >= 1 and len(skyportal.plans) == 1


def test_a_tried_request_whose_fate_stays_unknown_past_its_window_fails_not_forever(tmp_path, skyportal):

    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    skyportal.faults["POST"] = ["503"]
    assert _step(state, skyportal.url) == 1  # tried, unanswered
    skyportal.faults["GET"] = ["500", "500"]  # the list unanswered: whether it landed is unknown
    assert _step(state, skyportal.url) == 1 and rows(state)[0]["state"] == "pending"
    assert _step(state, skyportal.url, after=dt.timedelta(days=2)) == 0
    (row,) = rows(state)
    assert row["state"] == "failed" and "unknown at the end of its window" in row["reason"]


def test_status_says_what_became_of_the_request(tmp_path, skyportal, capsys):
    from mushrooms.tool.status import main

    state = parts_state(tmp_path, [(1, "PRELIMINARY", "exported")])
    assert _step(state, skyportal.url) == 0
    main(["--state", str(state)])
    out = capsys.readouterr().out
    assert "telescope winter (skyportal): exported at Palomar" in out and "SkyPortal request sent (id 1)" in out
    assert TOKEN not in out
