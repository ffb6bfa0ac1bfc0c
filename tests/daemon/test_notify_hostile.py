"""``[notify]`` against a hostile or broken webhook (issue 52, findings 2, 3, 7 and 8).

2. A webhook URL that cannot be parsed is refused at start with one line that
   does not show it (``mushrooms run`` exits 2), and one message that cannot
   be sent never kills the sender.
3. A webhook that trickles its answer is cut at the POST's deadline (the
   socket closed, whatever keeps coming); one sender thread and a bounded
   queue whatever the webhook does, and messages flow again once it answers.
7. Text from outside (Kowalski's refusal, an error, a notice's id) reaches the
   chat with its markup and its control and bidi characters neutralised.
8. A redirect is never followed: a 3xx is a failure, logged as one.

Real parts: pytest-httpserver and raw sockets on 127.0.0.1, the real daemon
for the start-up refusal.
"""

from __future__ import annotations

import json
import logging
import select
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest

from daemon_helpers import Daemon, write_config
from hostile_http import HostileServer, drip
from mushrooms.daemon.credentials import CredentialsError
from mushrooms.daemon.ops.announce import NotifyingSink, job_failed, open_webhook, submission_trouble
from mushrooms.daemon.ops.metrics import ServiceMetrics
from mushrooms.daemon.ops.webhook import Webhook
from mushrooms.daemon.ops.webhook_settings import NotifyConfig
from mushrooms.daemon.sinks import MemorySink

SECRET = "s3cr3t-hook-token"
PATH = f"/services/T000/B000/{SECRET}"
#: What a trickling webhook sends, one byte every 0.2 s: a status line and a header that never end.
TRICKLE = b"HTTP/1.1 200 OK\r\nX-Slow: " + b"." * 100_000


def _wait(predicate, timeout_s: float, what: str) -> None:
    """Wait for ``predicate`` (``timeout_s`` is only a hang guard)."""
    end = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def _sender_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("mushrooms-webhook")]


def _said(caplog) -> str:
    return "\n".join(r.getMessage() for r in caplog.records if r.name.startswith("mushrooms"))


# ------------------------------------------------------------------ 2: a URL that cannot be parsed
BAD_URLS = {
    "no scheme (a Slack URL pasted without https://)": f"hooks.slack.com{PATH}",
    "a scheme that is not http(s)": f"ftp://hooks.example{PATH}",
    "an IPv6 literal not closed": f"https://[::1{PATH}",
    "an IPv6 literal that is no address": f"https://[fe80::zz]{PATH}",
    "no host": f"https://{PATH}",
    "a port out of range": f"https://hooks.example:99999{PATH}",
    "a port that is no number": f"https://hooks.example:44x{PATH}",
    "a space inside": f"https://hooks.example{PATH} x",
    "credentials inside": f"https://user:{SECRET}@hooks.example/hook",
}


def test_a_webhook_url_that_cannot_be_parsed_is_refused_in_one_line_that_does_not_show_it():
    for why, url in BAD_URLS.items():
        with pytest.raises(CredentialsError) as caught:
            hook = open_webhook(NotifyConfig(target="slack"), environ={"MUSHROOMS_NOTIFY_URL": url})
            hook.close(0.1)  # (today: accepted, and the thread dies at its first message)
        said = str(caught.value)
        assert "\n" not in said and "MUSHROOMS_NOTIFY_URL" in said, why
        assert SECRET not in said and "hooks." not in said and "services" not in said, (why, said)
    for url in ("https://hooks.slack.com/services/T0/B0/x", "http://127.0.0.1:8080/hook", "http://[::1]:8080/hook",
                "https://[2001:db8::1]/hook?token=x", "https://hooks.example"):
        hook = open_webhook(NotifyConfig(target="json"), environ={"MUSHROOMS_NOTIFY_URL": url})
        assert hook is not None, url
        hook.close(0.1)


def test_mushrooms_run_refuses_a_bad_webhook_url_with_exit_2_before_touching_the_state(broker, daemons, tmp_path):
    topic, out, group = broker.fresh_topics()
    cfg = write_config(tmp_path / "config.toml", topic, out, group, '\n[notify]\ntarget = "slack"\n')
    state = tmp_path / "s.sqlite"
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)],
               env={"MUSHROOMS_NOTIFY_URL": f"hooks.slack.com{PATH}"})
    daemons.append(d)
    end = time.monotonic() + 120  # hang guard: today the service starts and runs
    while d.proc.poll() is None:
        assert "event=service_ready" not in d.text(), "the service started with a webhook URL it cannot use"
        assert time.monotonic() < end, "the service neither started nor stopped"
        time.sleep(0.1)
    text = d.text()
    errors = [line for line in text.splitlines() if "error" in line.lower()]
    assert d.proc.returncode == 2, text
    assert len(errors) == 1 and "webhook URL" in errors[0] and "Traceback" not in text, text
    assert SECRET not in text and "hooks.slack.com" not in text
    assert not state.exists()  # refused before the state file was created


class _Unprintable:
    def __str__(self) -> str:
        raise RuntimeError(f"cannot print {PATH}")


def test_one_message_that_cannot_be_sent_never_kills_the_sender(httpserver, caplog):
    httpserver.expect_request(PATH, method="POST").respond_with_data("ok")
    caplog.set_level(logging.INFO, logger="mushrooms")
    hook = Webhook(httpserver.url_for(PATH), "json", timeout_s=2)
    hook.post("plan_published", "S1: first", {"plan_id": _Unprintable()})
    hook.post("plan_published", "S1: second", {"plan_id": "p2"})
    _wait(lambda: len(httpserver.log) == 1 or not hook._thread.is_alive(), 20, "the second message")
    assert hook._thread.is_alive(), "the sender died at the first message"
    hook.close(2)
    said = [json.loads(req.get_data())["text"] for req, _ in httpserver.log]
    assert said == ["S1: second"] and (hook.sent, hook.failed) == (1, 1)
    assert "event=notify_failed kind=plan_published" in _said(caplog)
    assert SECRET not in _said(caplog) and "Traceback" not in caplog.text


# ------------------------------------------------------------------ 3: a webhook that trickles
def test_a_trickling_webhook_is_cut_at_the_posts_deadline_and_its_socket_closed(caplog):
    caplog.set_level(logging.INFO, logger="mushrooms")
    with HostileServer(drip(TRICKLE, 0.2)) as server:
        hook = Webhook(server.url + PATH, "slack", timeout_s=1.0)
        hook.post("plan_published", "S1: new plan")
        # the server's drip ends only when the client closed the socket (send fails); 1000 bytes took 200 s
        _wait(lambda: len(server.sent) == 1, 30, "the webhook's socket to be closed")
        assert server.sent[0] < 1000  # cut while trickling, not at the end of the trickle
        _wait(lambda: hook.failed == 1, 10, "the failure to be counted")
        assert hook.sent == 0 and len(_sender_threads()) == 1  # one sender, no thread left per POST
        hook.close(0.5)
    said = _said(caplog)
    assert "event=notify_failed kind=plan_published" in said and "error=deadline" in said
    assert SECRET not in said


class _Trickler:
    """A webhook on loopback that answers one byte every 0.2 s, or at once after :meth:`recover`.

    At each new connection it notes how many earlier ones the client still holds open
    (:attr:`open_at_accept`): the client sends nothing after its request, so an earlier
    connection whose socket is readable (end of file, or reset) was closed by the client.
    """

    def __init__(self) -> None:
        self._sock = socket.create_server(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self._sock.getsockname()[1]}"
        self.conns: list[socket.socket] = []
        self.open_at_accept: list[int] = []
        self.texts: list[str] = []
        self.healthy = False
        threading.Thread(target=self._serve, daemon=True).start()

    def recover(self) -> None:
        self.healthy = True

    def close(self) -> None:
        self._sock.close()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self._sock.accept()
            except OSError:
                return
            live = [c for c in self.conns if c.fileno() >= 0]
            readable = select.select(live, [], [], 0)[0] if live else []
            self.open_at_accept.append(len(live) - len(readable))
            self.conns.append(conn)
            threading.Thread(target=self._one, args=(conn,), daemon=True).start()

    def _one(self, conn: socket.socket) -> None:
        data = b""
        try:
            while b"\r\n\r\n" not in data:
                data += conn.recv(65536) or b"!"
            head, body = data.split(b"\r\n\r\n", 1)
            n = int(next(v for k, v in (h.split(b":", 1) for h in head.split(b"\r\n")[1:])
                         if k.lower() == b"content-length"))
            while len(body) < n:
                body += conn.recv(65536) or b"!"
            self.texts.append(json.loads(body)["text"])
            if self.healthy:
                conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\nConnection: close\r\n\r\nok")
            else:
                for i in range(len(TRICKLE)):
                    conn.sendall(TRICKLE[i:i + 1])
                    time.sleep(0.2)
        except (OSError, ValueError, StopIteration):
            pass
        finally:
            conn.close()


def test_one_sender_and_a_bounded_queue_and_messages_flow_again_once_the_webhook_answers(caplog):
    caplog.set_level(logging.INFO, logger="mushrooms")
    server = _Trickler()
    try:
        hook = Webhook(server.url + PATH, "json", timeout_s=0.4, max_pending=3)
        for k in range(12):
            hook.post("submission_failed", f"message {k}")
        _wait(lambda: hook.failed >= 3, 30, "three POSTs to be given up on")
        assert len(_sender_threads()) == 1  # one sender thread, none per POST
        server.recover()
        hook.post("plan_published", "after recovery")
        _wait(lambda: "after recovery" in server.texts, 30, "a message after the recovery")
        hook.close(5)
    finally:
        server.close()
    assert len(server.open_at_accept) >= 4 and max(server.open_at_accept) == 0  # one POST, one socket at a time
    assert hook.dropped >= 12 - 3 - 1  # the queue holds 3: older messages made room for newer ones
    assert hook.sent + hook.failed + hook.dropped == 13 and hook.sent >= 1
    assert server.texts[-1] == "after recovery" and "message 11" in server.texts  # the newest were kept
    said = _said(caplog)
    assert "event=notify_dropped" in said and SECRET not in said
    metrics = ServiceMetrics("test")
    metrics.watch(notify=hook.counts)
    page = metrics.render().decode()
    assert f'mushrooms_notify_messages_total{{outcome="dropped"}} {float(hook.dropped)}' in page
    assert f'mushrooms_notify_messages_total{{outcome="sent"}} {float(hook.sent)}' in page
    assert SECRET not in page


# ------------------------------------------------------------------ 8: redirects
@pytest.mark.parametrize("status", [301, 302, 303, 307, 308])
def test_a_redirect_is_never_followed_and_is_a_failure(httpserver, loopback, status, caplog):
    caplog.set_level(logging.INFO, logger="mushrooms")
    loopback.expect_request("/login").respond_with_data("welcome")
    httpserver.expect_request(PATH, method="POST").respond_with_data(
        "", status=status, headers={"Location": loopback.url_for("/login")})
    hook = Webhook(httpserver.url_for(PATH), "slack", timeout_s=2)
    hook.post("plan_published", "S1: new plan")
    _wait(lambda: hook.sent + hook.failed == 1, 20, "the POST's outcome")
    hook.close(1)
    assert len(loopback.log) == 0  # the other host was never asked
    assert (hook.sent, hook.failed) == (0, 1)
    said = _said(caplog)
    assert f"event=notify_failed kind=plan_published http_status={status}" in said
    assert "notify_sent" not in said and "/login" not in said and SECRET not in said


# ------------------------------------------------------------------ 7: remote text in the chat
HOSTILE = ("<!channel> queue refused: <https://evil.example/login|log in to Kowalski to keep your queue> "
           "[log in](https://evil.example/x) @here ops@all.example \u202etxt.exe\u202c \x85\x1b[31m\u200b\ufeff\u2066ok\u2069\nnext")
#: What must not reach a chat: its markup, and characters that reorder, hide or break the text.
FORBIDDEN = ("<", ">", "](", "@here", "\u202e", "\u202c", "\x85", "\x1b", "\u200b", "\ufeff", "\u2066", "\u2069", "\n")


def _texts(server) -> list[dict]:
    return [json.loads(req.get_data()) for req, _ in server.log]


@pytest.mark.parametrize("target", ["slack", "json"])
def test_remote_text_reaches_the_chat_with_its_markup_and_control_characters_neutralised(httpserver, target):
    httpserver.expect_request(PATH, method="POST").respond_with_data("ok")
    sink = NotifyingSink(MemorySink(), Webhook(httpserver.url_for(PATH), target, timeout_s=2))
    sink.publish({"type": "submission", "submission_id": "s1", "superevent_id": "S1\u202e", "state": "rejected",
                  "queue_name": "ToO_<!here>", "target": "kowalski", "reason": HOSTILE})
    job_failed(sink, "S2", HOSTILE)
    submission_trouble(sink, "S3", "ToO_GW_S3_r1", 1, HOSTILE)
    _wait(lambda: len(httpserver.log) == 3, 20, "three messages")
    sink.close()
    bodies = _texts(httpserver)
    for body in bodies:
        strings = [v for v in body.values() if isinstance(v, str)]
        for s in strings:
            assert not any(bad in s for bad in FORBIDDEN), (target, s)
        text = body["text"]
        assert "&lt;!channel&gt; queue refused" in text and "&lt;https://evil.example/login|log in" in text
        assert "[log in] (https://evil.example/x)" in text and "@ here ops@all.example" in text
        assert "\\u202etxt.exe\\u202c" in text and "\\x85\\x1b[31m" in text and " next" in text
    assert bodies[0]["text"].startswith("S1\\u202e: queue ToO_&lt;!here&gt; (kowalski) was REJECTED: ")
    assert bodies[1]["text"].startswith("S2: planning FAILED: ")
    assert bodies[2]["text"].startswith("S3: queue ToO_GW_S3_r1 could not be submitted (attempt 1: ")


def test_a_huge_remote_text_is_cut_in_the_chat(httpserver):
    httpserver.expect_request(PATH, method="POST").respond_with_data("ok")
    hook = Webhook(httpserver.url_for(PATH), "slack", timeout_s=2)
    job_failed(NotifyingSink(MemorySink(), hook), "S1", "x" * 200_000)
    _wait(lambda: len(httpserver.log) == 1, 20, "the message")
    hook.close(1)
    text = _texts(httpserver)[0]["text"]
    assert text.startswith("S1: planning FAILED: xxx") and text.endswith("...") and len(text) <= 3000


def test_the_webhook_url_is_in_no_repr_or_count():
    hook = Webhook(f"http://127.0.0.1:9{PATH}", "slack", timeout_s=0.5)
    try:
        assert SECRET not in repr(hook) and SECRET not in repr(NotifyingSink(MemorySink(), hook))
        assert SECRET not in json.dumps(hook.counts())
    finally:
        hook.close(0.1)



# ------------------------------------------------------------------ the sender's own HTTP, guarded
def _self_signed(tmp_path: Path) -> tuple[Path, Path]:
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    try:
        subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj",
                        "/CN=localhost", "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost",
                        "-keyout", str(key), "-out", str(cert)], check=True, capture_output=True, timeout=60)
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"openssl cannot make a test certificate: {exc}")
    return cert, key


def _raw_server(family: int, host: str, script) -> tuple[socket.socket, list[int]]:
    """A one-connection server on loopback; ``script(conn)`` answers; the list gets the bytes it sent."""
    srv = socket.create_server((host, 0), family=family)
    sent: list[int] = []

    def serve() -> None:
        conn, _ = srv.accept()
        n = 0
        try:
            n = script(conn)
        except OSError:
            pass
        finally:
            sent.append(n)
            conn.close()

    threading.Thread(target=serve, daemon=True).start()
    return srv, sent


def _read_request(conn: socket.socket) -> bytes:
    data = b""
    while b"\r\n\r\n" not in data:
        data += conn.recv(65536) or b"\r\n\r\n"
    return data


def test_the_sender_speaks_tls_and_ipv6_skips_interim_answers_and_cuts_a_trickling_handshake(tmp_path, monkeypatch,
                                                                                           caplog):
    """Guards of the sender's own HTTP/1.1 (what ``urllib`` did before): none of this is a finding."""
    import ssl

    from pytest_httpserver import HTTPServer

    caplog.set_level(logging.INFO, logger="mushrooms")
    cert, key = _self_signed(tmp_path)
    monkeypatch.setenv("SSL_CERT_FILE", str(cert))  # the default context trusts the test certificate
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.load_cert_chain(cert, key)
    tls = HTTPServer(host="127.0.0.1", port=0, ssl_context=context)
    tls.expect_request(PATH, method="POST").respond_with_data("ok")
    tls.start()
    try:
        hook = Webhook(f"https://127.0.0.1:{tls.port}{PATH}", "slack", timeout_s=5)
        hook.post("plan_published", "over TLS")
        _wait(lambda: hook.sent + hook.failed == 1, 20, "the TLS POST")
        hook.close(1)
        assert hook.sent == 1 and json.loads(tls.log[0][0].get_data()) == {"text": "over TLS"}
    finally:
        tls.stop()

    def interim_then_ok(conn: socket.socket) -> int:
        request = _read_request(conn)
        assert b"Host: [::1]:" in request and request.startswith(f"POST {PATH} HTTP/1.1\r\n".encode())
        answer_bytes = b"HTTP/1.1 100 Continue\r\n\r\nHTTP/1.1 204 No Content\r\nConnection: close\r\n\r\n"
        conn.sendall(answer_bytes)
        return len(answer_bytes)

    srv, _ = _raw_server(socket.AF_INET6, "::1", interim_then_ok)
    hook = Webhook(f"http://[::1]:{srv.getsockname()[1]}{PATH}", "json", timeout_s=5)
    hook.post("plan_published", "over IPv6")
    _wait(lambda: hook.sent + hook.failed == 1, 20, "the IPv6 POST")
    hook.close(1)
    srv.close()
    assert hook.sent == 1

    def trickled_handshake(conn: socket.socket) -> int:  # a TLS record header, then its 16 kB one byte at a time
        conn.recv(65536)
        conn.sendall(b"\x16\x03\x03\x40\x00")
        for n in range(16384):
            conn.sendall(b"\x00")
            time.sleep(0.2)
        return n

    srv, sent = _raw_server(socket.AF_INET, "127.0.0.1", trickled_handshake)
    hook = Webhook(f"https://127.0.0.1:{srv.getsockname()[1]}{PATH}", "slack", timeout_s=1.0)
    hook.post("plan_published", "trickled")
    _wait(lambda: len(sent) == 1, 30, "the trickled handshake to be cut")
    hook.close(1)
    srv.close()
    assert hook.failed == 1 and "error=deadline" in _said(caplog) and SECRET not in _said(caplog)


def test_a_reload_that_changes_the_outbound_sink_keeps_telling_the_webhook(broker, daemons, tmp_path, httpserver):
    """Found while attacking this change: a SIGHUP with a new ``[outbound]`` dropped the webhook silently."""
    from daemon_helpers import notice_bytes

    httpserver.expect_request(PATH, method="POST").respond_with_data("ok")
    topic, out, group = broker.fresh_topics()
    out2 = out + "-after-reload"
    broker.ensure_topic(out2)
    cfg = write_config(tmp_path / "config.toml", topic, out, group, '\n[notify]\ntarget = "json"\ntimeout_s = 2.0\n')
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(tmp_path / "s.sqlite")],
               env={"MUSHROOMS_NOTIFY_URL": httpserver.url_for(PATH)})
    daemons.append(d)
    d.wait_log("event=service_ready", 120)
    cfg.write_text(cfg.read_text().replace(f'topic = "{out}"', f'topic = "{out2}"'))
    d.proc.send_signal(signal.SIGHUP)
    d.wait_log("event=config_reloaded", 60)
    broker.produce(topic, notice_bytes("MS181101ab-preliminary.json", "MS181101ab"), key=b"MS181101ab")
    reader = broker.reader(out2, group + "-reader")
    try:
        reader.wait_for(lambda ms: any(m.get("type") == "plan" for m in ms), 180, alive=d.alive)
    finally:
        reader.close()
    end = time.monotonic() + 30  # hang guard: the message follows the publication within timeout_s
    while not any(json.loads(req.get_data()).get("event") == "plan_published" for req, _ in httpserver.log):
        d.alive()
        assert time.monotonic() < end, "the plan was published after the reload, but the webhook was not told"
        time.sleep(0.1)
    assert d.stop() == 0
    assert SECRET not in d.text()
