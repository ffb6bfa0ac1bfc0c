"""The submission clients against hostile neighbours: redirects, drips, cut and endless answers, bad tokens.

Every server here is a raw socket on loopback (``hostile_http.py``) that
answers the way a broken proxy or an attacker would; the clients are the
daemon's own (:mod:`mushrooms.daemon.submission.remote`) and the classification is the
one the submitter and ``mushrooms submit`` use (:func:`send_queue`).
"""

from __future__ import annotations

import json

import pytest

from hostile_http import HostileServer, answer, drip, endless, raw
from mushrooms.daemon.credentials import CredentialsError, load_executed_token, load_submit_token
from mushrooms.daemon.submission import remote
from mushrooms.daemon.submission.remote import KowalskiQueue, SkyPortalPlans, Unreachable
from mushrooms.daemon.submission.submitter import send_queue

TOKEN = "s3cr3t-token-0123456789abcdef"
QUEUE = {"queue_name": "ToO_GW_S1_r1_1", "queue_type": "list", "validity_window_mjd": [60000.0, 60001.0],
         "user": "mushrooms", "targets": [{"field_id": 1, "filter_id": 1, "exposure_time": 30.0}]}
OK_JSON = json.dumps({"status": "success", "message": "submitted", "data": {}}).encode()


def test_a_redirected_get_is_refused_and_the_token_never_reaches_the_other_host() -> None:
    with HostileServer(answer("200 OK", b'{"status": "success", "data": []}')) as other:
        with HostileServer(answer("302 Found", headers={"Location": other.url + "/steal"})) as first:
            client = KowalskiQueue(first.url, TOKEN, 2.0)
            with pytest.raises(RuntimeError, match="302.*not followed"):
                client.queues()
        assert other.requests == []  # nothing followed: the token went to the configured host only
    assert first.requests[0]["headers"]["authorization"] == f"Bearer {TOKEN}"


def test_a_put_answered_307_is_a_refusal_with_its_reason_not_a_retry() -> None:
    with HostileServer(answer("307 Temporary Redirect", headers={"Location": "http://127.0.0.1:9/x"})) as s:
        verdict = send_queue(KowalskiQueue(s.url, TOKEN, 2.0), QUEUE, QUEUE["queue_name"])
    assert verdict.state == "rejected"
    assert "307" in verdict.reason and "http://127.0.0.1:9/x" in verdict.reason and "not followed" in verdict.reason
    assert len(s.requests) == 1


def test_a_skyportal_post_answered_302_is_not_submitted() -> None:
    with HostileServer(answer("200 OK", OK_JSON)) as other:
        with HostileServer(answer("302 Found", headers={"Location": other.url + "/login"})) as first:
            verdict = send_queue(SkyPortalPlans(first.url, TOKEN, 2.0), {"plan_name": "GW_S1_r1"}, "ToO_GW_S1_r1")
    assert verdict.state == "rejected" and "302" in verdict.reason
    assert other.requests == []


@pytest.mark.parametrize("token", ["abc\ndef-secret", "abc\r\nX-Evil: 1", "tok\u20acen-secret", "tab\there"])
def test_a_token_with_a_line_break_or_outside_latin1_is_refused_where_it_is_loaded(tmp_path, token) -> None:
    with pytest.raises(CredentialsError) as caught:
        load_submit_token({"MUSHROOMS_SUBMIT_TOKEN": token})
    message = str(caught.value)
    assert "\n" not in message and "MUSHROOMS_SUBMIT_TOKEN" in message
    for part in token.replace("\r", "\n").replace("\t", "\n").split("\n"):
        assert part.strip() not in message or len(part.strip()) < 4
    (tmp_path / "submit_token").write_text(token + "\n")
    with pytest.raises(CredentialsError, match="submit_token"):
        load_submit_token({"CREDENTIALS_DIRECTORY": str(tmp_path)})
    with pytest.raises(CredentialsError):
        load_executed_token({"MUSHROOMS_EXECUTED_TOKEN": token})


def test_a_token_with_a_line_break_makes_the_queue_tool_say_one_line(tmp_path, monkeypatch, capsys) -> None:
    from mushrooms.cli import main

    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", "first-half\nsecond-half")
    assert main(["queue", "list", "--url", "http://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "half" not in err and len(err.strip().splitlines()) == 1


def test_an_answer_dripped_one_byte_at_a_time_is_cut_at_the_request_deadline() -> None:
    reply = b"HTTP/1.1 200 OK\r\nContent-Length: %d\r\n\r\n%s" % (len(OK_JSON), OK_JSON)
    with HostileServer(drip(reply, 0.05)) as s:  # every recv gets a byte well within timeout_s
        verdict = send_queue(KowalskiQueue(s.url, TOKEN, 0.5), QUEUE, QUEUE["queue_name"])
    assert verdict.state == "retry" and "deadline" in verdict.reason
    assert s.sent and s.sent[0] < len(reply)  # the client hung up before the drip ended


def test_an_answer_larger_than_the_cap_is_not_read_whole() -> None:
    with HostileServer(endless()) as s:
        with pytest.raises(RuntimeError, match="larger than"):
            KowalskiQueue(s.url, TOKEN, 5.0).queues()
        verdict = send_queue(KowalskiQueue(s.url, TOKEN, 5.0), QUEUE, QUEUE["queue_name"])
    assert verdict.state == "retry" and "larger than" in verdict.reason
    assert s.sent and max(s.sent) < 64 * getattr(remote, "ANSWER_BYTES", 2**20)  # the client stopped reading (the server had 256 MiB)


@pytest.mark.parametrize("reply", [
    b"HTTP/1.1 200 OK\r\nContent-Length: 100\r\n\r\n{\"status\"",  # cut in the body
    b"HTTP/1.1 200 OK\r\nContent-Le",  # cut in the headers
    b"SSH-2.0-OpenSSH_9.6\r\n\r\n",  # not HTTP
    b"",  # closed without a word
])
def test_a_cut_or_non_http_answer_is_unreachable_and_retried(reply) -> None:
    with HostileServer(raw(reply)) as s:
        client = KowalskiQueue(s.url, TOKEN, 2.0)
        try:  # no answer, or one that says what is wrong with it: never an exception of http.client
            assert client.put(QUEUE).problem
        except Unreachable:
            pass
        verdict = send_queue(client, QUEUE, QUEUE["queue_name"])
    assert verdict.state == "retry" and TOKEN not in verdict.reason


def test_a_200_that_is_not_json_is_not_submitted() -> None:
    with HostileServer(answer("200 OK", b"<html><body>Welcome to the captive portal</body></html>",
                              {"Content-Type": "text/html"})) as s:
        for client, body in ((KowalskiQueue(s.url, TOKEN, 2.0), QUEUE),
                             (SkyPortalPlans(s.url, TOKEN, 2.0), {"plan_name": "GW_S1_r1"})):
            verdict = send_queue(client, body, "ToO_GW_S1_r1_1")
            assert verdict.state == "retry" and "not JSON" in verdict.reason


def test_the_queue_tool_survives_a_non_http_answer_and_prints_one_short_line(monkeypatch, capsys) -> None:
    from mushrooms.cli import main

    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", TOKEN)
    with HostileServer(raw(b"garbage that is not HTTP\r\n\r\n")) as s:
        assert main(["queue", "list", "--url", s.url]) == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    page = ("<html>\n" + "error line\n" * 5000 + "</html>").encode()
    with HostileServer(answer("500 Internal Server Error", page)) as s:
        assert main(["queue", "list", "--url", s.url]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and len(err) < 600
