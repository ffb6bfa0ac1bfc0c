"""``[notify]``: the observer on call is told, through a webhook on a local server, and a hanging one holds nothing up.

The webhook poster against pytest-httpserver (Slack and generic JSON bodies, a
server that hangs, the URL never logged), then the real daemon: a notice ->
a "new plan" message; Kowalski's stand-in down -> the "could not be
submitted" message.
"""

from __future__ import annotations

import json
import logging
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from werkzeug.wrappers import Response

from daemon_helpers import Daemon, notice_bytes, write_config
from mushrooms.daemon.ops.announce import NotifyingSink, announcement, open_webhook
from mushrooms.daemon.credentials import CredentialsError
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.ops.webhook import Webhook
from mushrooms.daemon.ops.webhook_settings import NotifyConfig

SECRET_PATH = "/services/T000/B000/s3cr3t-hook-token"


def _bodies(httpserver) -> list[dict]:
    return [json.loads(req.get_data()) for req, _ in httpserver.log]


def _wait(predicate, timeout_s: float, what: str, alive=None) -> None:
    end = time.monotonic() + timeout_s
    while not predicate():
        if alive is not None:
            alive()
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def test_slack_and_json_bodies_reach_the_server(httpserver):
    httpserver.expect_request(SECRET_PATH, method="POST").respond_with_data("ok")
    slack = Webhook(httpserver.url_for(SECRET_PATH), "slack", timeout_s=2)
    generic = Webhook(httpserver.url_for(SECRET_PATH), "json", timeout_s=2)
    assert slack.post("plan_published", "S1: new plan", {"plan_id": "p1"})
    assert generic.post("plan_published", "S1: new plan", {"plan_id": "p1"})
    _wait(lambda: len(httpserver.log) == 2, 10, "two posts")
    slack.close(), generic.close()
    bodies = sorted(_bodies(httpserver), key=len)
    assert bodies[0] == {"text": "S1: new plan"}
    assert bodies[1]["event"] == "plan_published" and bodies[1]["text"] == "S1: new plan"
    assert bodies[1]["plan_id"] == "p1" and bodies[1]["source"] == "mushrooms"
    assert all(req.headers["Content-Type"] == "application/json" for req, _ in httpserver.log)
    assert (slack.sent, generic.sent) == (1, 1)


def test_a_hanging_webhook_never_blocks_the_poster_and_is_given_up_on(httpserver, caplog):
    release = threading.Event()

    def hang(request):
        release.wait(20)
        return Response("late", 200)

    httpserver.expect_request(SECRET_PATH, method="POST").respond_with_handler(hang)
    hook = Webhook(httpserver.url_for(SECRET_PATH), "slack", timeout_s=0.5, max_pending=3)
    caplog.set_level(logging.INFO, logger="mushrooms.daemon.webhook")
    t0 = time.perf_counter()
    queued = [hook.post("plan_published", f"message {k}") for k in range(6)]
    posting_s = time.perf_counter() - t0
    try:
        _wait(lambda: hook.failed >= 1, 10, "the first post to be given up on")
    finally:
        release.set()  # the test server is single-threaded: never leave it hanging for the next test
    hook.close(timeout_s=5)
    assert all(queued)  # the bounded queue makes room (drops the oldest) instead of waiting
    assert hook.dropped >= 2
    assert posting_s < hook.timeout_s  # six posts took less than one request's deadline: none waited for it
    text = "\n".join(r.getMessage() for r in caplog.records if r.name.startswith("mushrooms"))  # not the server's
    assert "event=notify_failed" in text and "event=notify_dropped" in text
    assert "s3cr3t" not in text and "s3cr3t" not in repr(hook)


def test_the_url_is_a_secret_from_the_environment_or_a_credential(tmp_path):
    assert open_webhook(NotifyConfig()) is None  # off by default: no URL needed
    with pytest.raises(CredentialsError, match="MUSHROOMS_NOTIFY_URL"):
        open_webhook(NotifyConfig(target="slack"), environ={})
    (tmp_path / "notify_url").write_text("http://127.0.0.1:9/hook\n")
    hook = open_webhook(NotifyConfig(target="json"), environ={"CREDENTIALS_DIRECTORY": str(tmp_path)})
    assert hook is not None and hook.target == "json"
    hook.close(0.1)
    with pytest.raises(ValueError, match="target must be one of off, slack, json"):
        NotifyConfig(target="email")


def test_each_outbound_message_is_said_in_words(httpserver):
    httpserver.expect_request(SECRET_PATH, method="POST").respond_with_data("ok")
    memory = MemorySink()
    sink = NotifyingSink(memory, Webhook(httpserver.url_for(SECRET_PATH), "json", timeout_s=2))
    sink.publish({"type": "withdrawal", "withdrawal_id": "w1", "superevent_id": "S1", "plan_ids": ["a", "b"],
                  "reason": "RETRACTION notice"})
    sink.publish({"type": "submission", "submission_id": "s1", "superevent_id": "S1", "state": "failed",
                  "queue_name": "ToO_GW_S1_r1", "target": "kowalski", "reason": "HTTP 500"})
    sink.publish({"type": "plan_final", "plan_id": "p1", "superevent_id": "S1", "reason": "The first plan stands."})
    _wait(lambda: len(httpserver.log) == 3, 10, "three posts")
    sink.close()
    assert [m["type"] for m in memory.messages] == ["withdrawal", "submission", "plan_final"]
    said = {b["event"]: b["text"] for b in _bodies(httpserver)}
    assert said["withdrawn"] == "S1 was retracted: 2 plan(s) withdrawn (RETRACTION notice)."
    assert "FAILED to reach the queue: HTTP 500" in said["submission_failed"]
    assert said["plan_final"] == "S1: plan p1 is final. The first plan stands."
    assert announcement({"type": "submission_unknown"}) is None


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # nothing listens here once the socket is closed


def test_the_daemon_tells_the_webhook_of_a_plan_and_of_kowalski_down(broker, daemons, tmp_path: Path, httpserver):
    httpserver.expect_request(SECRET_PATH, method="POST").respond_with_data("ok")
    tag = time.time_ns()
    topic, out, group = f"gwalert-{tag}", f"plans-{tag}", f"mushrooms-{tag}"
    broker.ensure_topic(topic)
    broker.ensure_topic(out)
    extra = (f'\n[notify]\ntarget = "json"\ntimeout_s = 2.0\n'
             f'\n[submit]\ntarget = "kowalski"\nurl = "http://127.0.0.1:{_closed_port()}"\ntimeout_s = 1.0\n'
             "retry_initial_s = 0.5\nretry_max_s = 1.0\n")
    cfg = write_config(tmp_path / "config.toml", topic, out, group, extra)
    env = {"MUSHROOMS_NOTIFY_URL": httpserver.url_for(SECRET_PATH), "MUSHROOMS_SUBMIT_TOKEN": "tok-123"}
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state",
                          str(tmp_path / "s.sqlite")], env=env)
    daemons.append(d)
    d.wait_log("event=service_ready", 120)
    broker.produce(topic, notice_bytes("MS181101ab-preliminary.json", "MS181101ab"), key=b"MS181101ab")
    events = lambda: [b["event"] for b in _bodies(httpserver)]  # noqa: E731
    _wait(lambda: "plan_published" in events() and "submission_failing" in events(), 180, "both messages",
          alive=d.alive)
    assert d.stop() == 0
    said = {b["event"]: b for b in _bodies(httpserver)}
    plan = said["plan_published"]
    assert plan["superevent_id"] == "MS181101ab" and plan["revision"] == 1
    assert plan["text"].startswith("MS181101ab: new ZTF plan, revision 1: ") and "exposures from" in plan["text"]
    failing = said["submission_failing"]["text"]
    base = f"ToO_GW_MS181101ab_{plan['plan_id'].removeprefix('mushrooms-')[:12]}"  # the one naming rule
    from mushrooms.daemon.state.store import Store
    from mushrooms.daemon.submission.rows import submissions

    store = Store(tmp_path / "s.sqlite")
    (names,) = [s.queue_names() for s in submissions(store) if s.state == "pending"]  # the set it PUTs
    store.close()
    assert len(names) > 3 and all(n.startswith(f"{base}_") for n in names), names
    few = f"{names[0]}, {names[1]}, {names[2]} +{len(names) - 3} more"  # a few names, then how many more
    assert failing.startswith(f"MS181101ab: queues {few} could not be submitted (attempt 1:"), failing
    assert said["submission_failing"]["queue_names"] == names
    assert failing.endswith("retrying")
    assert [e for e in events() if e == "submission_failing"] == ["submission_failing"]  # said once, not per retry
    assert SECRET_PATH not in d.text() and "s3cr3t" not in d.text()
    stored = b"".join(p.read_bytes() for p in tmp_path.glob("s.sqlite*"))
    status = subprocess.run([sys.executable, "-m", "mushrooms.cli", "status", "--json", "--state",
                             str(tmp_path / "s.sqlite")], capture_output=True, text=True, timeout=120, env={**os.environ, **env})
    assert stored and b"s3cr3t" not in stored  # the URL is in no state, outbox row or submission row
    assert "MS181101ab" in status.stdout and "s3cr3t" not in status.stdout + status.stderr
    print("\n".join(f"{b['event']}: {b['text']}" for b in _bodies(httpserver)))
