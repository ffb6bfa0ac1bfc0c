"""``mushrooms preflight``: the real installation checked end to end before an event (issue 52, finding 10).

Against librdkafka's mock cluster on loopback (behind a SASL/OAUTHBEARER login
and an OIDC token endpoint for the credentials: ``sasl_gate.py`` says why),
a Kowalski and a SkyPortal stand-in (pytest-httpserver) with good and bad
tokens, a webhook stand-in, and real files.  One line per check, exit 0 / 1 / 2.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from werkzeug import Request, Response

from daemon_helpers import REPO
from sasl_gate import SaslGate, TokenEndpoint

from mushrooms.cli import main
from mushrooms.daemon.credentials import Credentials
from mushrooms.daemon.settings import KafkaConfig

TOKEN = "kowalski-G00D-t0ken-4f1c"
HOOK_SECRET = "T000/B000/XXXXsecretXXXX"


def _lines(out: str) -> dict[str, tuple[str, str]]:
    """check name -> (status, reason) from preflight's stdout."""
    got = {}
    for line in out.splitlines():
        status, _, rest = line.partition(" ")
        name, _, reason = rest.strip().partition(": ")
        if status in ("ok", "FAIL", "skip"):
            got[name] = (status, reason)
    return got


def _kowalski(server, token: str = TOKEN) -> None:
    """Kowalski's GET /api/triggers/ztf as its middleware answers (docs/design/submission.md)."""

    def answer(request: Request) -> Response:
        auth = request.headers.get("Authorization")
        if auth is None:
            return Response(json.dumps({"status": "error", "message": "auth required"}), 401,
                            content_type="application/json")
        if auth != f"Bearer {token}":
            return Response(json.dumps({"status": "error", "message": "token is invalid"}), 400,
                            content_type="application/json")
        return Response(json.dumps({"status": "success", "message": "retrieved", "data": [
            {"queue_name": "ToO_other", "validity_window_mjd": [61000.1, 61000.2], "queue": "[]"}]}), 200,
            content_type="application/json")

    server.expect_request("/api/triggers/ztf", method="GET").respond_with_handler(answer)


def _config(tmp: Path, bootstrap: str, topic: str, extra: str = "") -> Path:
    cfg = tmp / "config.toml"
    cfg.write_text(f'[daemon]\nstate_path = "{tmp}/state/mushrooms-state.sqlite"\n\n'
                   f'[kafka]\nbootstrap = "{bootstrap}"\ntopics = ["{topic}"]\nassignment = "manual"\n\n'
                   f'[outbound]\ndirectory = "{tmp}/outbox"\n\n{extra}')
    return cfg


def _preflight(capsys, *args: str) -> tuple[int, dict[str, tuple[str, str]], str]:
    capsys.readouterr()
    code = main(["preflight", *args])
    out, err = capsys.readouterr()
    return code, _lines(out), out + err


@pytest.fixture
def topic(broker) -> str:
    return broker.fresh_topics()[0]


def test_preflight_is_a_command_with_help(capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["preflight", "--help"])
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: mushrooms preflight") and "--notify-test" in out


def test_all_ok_against_a_local_broker_and_kowalski_with_a_good_token(broker, topic, loopback, tmp_path,
                                                                     monkeypatch, capsys) -> None:
    _kowalski(loopback)
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", TOKEN)
    cfg = _config(tmp_path, broker.bootstrap, topic,
                  f'[submit]\ntarget = "kowalski"\nurl = "{loopback.url_for("/").rstrip("/")}"\n')
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "10")
    assert code == 0, text
    assert set(lines) == {"config", "credentials", "kafka", "submission", "submission_parts", "webhook", "state",
                          "directories", "outbox"}, text
    assert all(status in ("ok", "skip") for status, _ in lines.values()), text
    assert f"{topic}: 4 partition(s)" in lines["kafka"][1]
    assert "group mushrooms-ztf: committed offsets on 0 of 4 partition(s)" in lines["kafka"][1]
    assert lines["submission"][0] == "ok" and "1 queue(s) listed" in lines["submission"][1]
    assert lines["credentials"][0] == "skip" and lines["webhook"][0] == "skip"
    assert TOKEN not in text
    assert not (tmp_path / "state").exists() and not (tmp_path / "outbox").exists()  # nothing created


def test_a_bad_or_missing_token_fails_without_being_shown(broker, topic, loopback, tmp_path, monkeypatch,
                                                          capsys) -> None:
    _kowalski(loopback)
    cfg = _config(tmp_path, broker.bootstrap, topic,
                  f'[submit]\ntarget = "kowalski"\nurl = "{loopback.url_for("/").rstrip("/")}"\n')
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", "expired-tok-9d2e")
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "10")
    assert code == 1 and lines["submission"][0] == "FAIL", text
    assert "token refused" in lines["submission"][1] and "token is invalid" in lines["submission"][1]
    assert "expired-tok-9d2e" not in text and lines["kafka"][0] == "ok"
    assert text.rstrip().splitlines()[-1].startswith("preflight: 1 check(s) failed (submission)")
    monkeypatch.delenv("MUSHROOMS_SUBMIT_TOKEN")
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "10")
    assert code == 1 and "submission token not found" in lines["submission"][1]


def test_a_missing_topic_and_an_unreachable_broker_fail(broker, loopback, tmp_path, capsys) -> None:
    cfg = _config(tmp_path, broker.bootstrap, "igwn.gwalert.nowhere")
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "10")
    assert code == 1 and lines["kafka"][0] == "FAIL", text
    assert "igwn.gwalert.nowhere: Broker: Unknown topic or partition" in lines["kafka"][1]
    assert "igwn.gwalert.nowhere" not in broker.producer.list_topics(timeout=10).topics  # not created
    cfg = _config(tmp_path, "127.0.0.1:9", "igwn.gwalert")
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "2")
    assert code == 1 and lines["kafka"][0] == "FAIL", text
    assert "no answer within 2 s" in lines["kafka"][1] and "Connection refused" in lines["kafka"][1]


def test_gcn_credentials_good_and_bad_through_the_oidc_token_and_the_sasl_login(broker, topic, loopback) -> None:
    tokens = TokenEndpoint(loopback, "gcn-client-id", "gcn-S3cret-value")
    gate = SaslGate(broker.bootstrap, tokens)  # takes only the tokens that endpoint issued
    over = {"bootstrap.servers": gate.bootstrap, "security.protocol": "sasl_plaintext",
            "sasl.oauthbearer.token.endpoint.url": tokens.url}  # only where: gcn-kafka sets the rest, as for GCN
    kafka = KafkaConfig(topics=(topic,))
    from mushrooms.tool.preflight import kafka_check  # (imported here: the module is new in issue 52)

    try:
        status, _, reason = kafka_check(kafka, 15, Credentials("gcn-client-id", "gcn-S3cret-value", "test"), over)
        assert status == "ok", reason
        assert "OIDC token and SASL login accepted" in reason and f"{topic}: 4 partition(s)" in reason
        assert gate.authentications >= 1 and gate.refused == 0 and gate.subjects == {"gcn-client-id"}
        status, _, reason = kafka_check(kafka, 15, Credentials("gcn-client-id", "wrong-secret-77", "test"), over)
        assert status == "FAIL" and "credentials refused by the OIDC token endpoint" in reason, reason
        assert "invalid_client" in reason and "wrong-secret-77" not in reason
        # a token the endpoint never issued (an unsigned one): the broker side refuses the login
        refused = gate.refused
        unsigned = {**over, "sasl.oauthbearer.method": "default", "enable.sasl.oauthbearer.unsecure.jwt": True,
                    "sasl.oauthbearer.config": "principal=gcn-client-id"}
        status, _, reason = kafka_check(kafka, 15, Credentials("gcn-client-id", "gcn-S3cret-value", "test"),
                                        unsigned)
        assert status == "FAIL" and "credentials refused by the broker (SASL)" in reason, reason
        assert gate.refused > refused
    finally:
        gate.close()


def test_the_state_file_must_be_a_private_sqlite_file(tmp_path, capsys) -> None:
    import sqlite3

    state = tmp_path / "state"
    state.mkdir()
    cfg = _config(tmp_path, "127.0.0.1:9", "t")
    path = state / "mushrooms-state.sqlite"

    def check() -> tuple[str, str]:
        code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "0.5")
        assert code == 1  # (the broker at port 9 fails too)
        return lines["state"]

    assert check()[0] == "ok" and "not there yet, will be created in" in check()[1]
    os.mkfifo(path)
    assert check() == ("FAIL", f"{path} is a FIFO, not a SQLite state file")
    path.unlink()
    path.mkdir()
    assert check() == ("FAIL", f"{path} is a directory, not a SQLite state file")
    path.rmdir()
    path.write_text("not a database")
    path.chmod(0o600)
    assert check() == ("FAIL", f"{path}: not a SQLite file")
    path.unlink()
    sqlite3.connect(path).execute("CREATE TABLE t (x)").connection.close()
    path.chmod(0o644)
    status, reason = check()
    assert status == "FAIL" and "world-readable (mode 0644)" in reason
    path.chmod(0o600)
    status, reason = check()
    assert status == "ok" and "SQLite state file, mode 0600" in reason


def test_the_webhook_gets_a_test_message_only_when_asked(broker, topic, loopback, tmp_path, monkeypatch,
                                                         capsys) -> None:
    loopback.expect_request(f"/hook/{HOOK_SECRET}", method="POST").respond_with_data("ok")
    monkeypatch.setenv("MUSHROOMS_NOTIFY_URL", loopback.url_for(f"/hook/{HOOK_SECRET}"))
    cfg = _config(tmp_path, broker.bootstrap, topic, '[notify]\ntarget = "json"\n')
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 0 and lines["webhook"][0] == "ok" and "no message sent" in lines["webhook"][1], text
    assert not [r for r, _ in loopback.log if r.path.startswith("/hook/")]
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--notify-test")
    assert code == 0 and "test message accepted" in lines["webhook"][1], text
    (posted,) = [r for r, _ in loopback.log if r.path.startswith("/hook/")]
    assert json.loads(posted.get_data())["event"] == "preflight_test"
    assert HOOK_SECRET not in text and "XXXXsecretXXXX" not in text
    monkeypatch.setenv("MUSHROOMS_NOTIFY_URL", loopback.url_for("/gone/" + HOOK_SECRET))  # 500: no handler
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--notify-test")
    assert code == 1 and lines["webhook"][0] == "FAIL" and "not accepted" in lines["webhook"][1], text
    assert HOOK_SECRET not in text
    monkeypatch.setenv("MUSHROOMS_NOTIFY_URL", f"hooks.slack.com/services/{HOOK_SECRET}")  # pasted without https://
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--notify-test")
    assert code == 1 and "it does not start with https:// or http://" in lines["webhook"][1] and HOOK_SECRET not in text


def test_skyportal_token_and_its_permission(broker, topic, loopback, tmp_path, monkeypatch, capsys) -> None:
    perms = {"value": ["Manage observation plans", "Upload data"]}

    def profile(request: Request) -> Response:
        if request.headers.get("Authorization") != "token sp-token-1":
            return Response(json.dumps({"status": "error", "message": "Unauthorized"}), 401,
                            content_type="application/json")
        return Response(json.dumps({"status": "success", "data": {"username": "mushrooms-bot",
                                                                  "permissions": perms["value"]}}), 200,
                        content_type="application/json")

    loopback.expect_request("/api/internal/profile", method="GET").respond_with_handler(profile)
    cfg = _config(tmp_path, broker.bootstrap, topic,
                  f'[submit]\ntarget = "skyportal"\nurl = "{loopback.url_for("/").rstrip("/")}"\n')
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", "sp-token-1")
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 0 and "user mushrooms-bot, may manage observation plans" in lines["submission"][1], text
    perms["value"] = ["Upload data"]
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 1 and "lacks the permission 'Manage observation plans'" in lines["submission"][1], text
    monkeypatch.setenv("MUSHROOMS_SUBMIT_TOKEN", "sp-token-2")
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 1 and "token refused" in lines["submission"][1] and "sp-token-2" not in text


def test_a_bad_config_fails_and_bad_usage_exits_2(tmp_path, capsys) -> None:
    cfg = tmp_path / "config.toml"
    cfg.write_text("[kafka]\nassignment = \"sometimes\"\n")
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 1 and lines["config"][0] == "FAIL" and "assignment" in lines["config"][1], text
    assert all(status == "skip" for name, (status, _) in lines.items() if name != "config")
    for bad in ("nan", "inf", "0", "-1", "x"):
        with pytest.raises(SystemExit) as stop:
            main(["preflight", "--timeout", bad])
        assert stop.value.code == 2
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--set", "kafka")  # no KEY=VALUE
    assert code == 2 and not lines and "expected SECTION.KEY=VALUE" in text


def test_preflight_runs_as_a_command(broker, topic, tmp_path) -> None:
    cfg = _config(tmp_path, broker.bootstrap, topic)
    out = subprocess.run([sys.executable, "-m", "mushrooms.cli", "preflight", "--config", str(cfg)],
                         capture_output=True, text=True, timeout=120, cwd=REPO,
                         env={**os.environ, "PYTHONPATH": str(REPO)})
    assert out.returncode == 0, out.stdout + out.stderr
    assert "%3|" not in out.stderr and "Traceback" not in out.stderr  # librdkafka's own lines stay out
    assert out.stdout.rstrip().splitlines()[-1] == "preflight: all 9 checks ok or skipped"


def _old_kafka_clients(monkeypatch) -> None:
    """gcn-kafka 0.3.3 on confluent-kafka 2.10.1 (what loses GCN's token after an hour), through the real check."""
    from mushrooms.daemon.kafka import versions

    real = versions.kafka_client_problem
    installed = {"gcn-kafka": "0.3.3", "confluent-kafka": "2.10.1"}
    monkeypatch.setattr(versions, "kafka_client_problem",
                        lambda: real(version=installed.__getitem__, librdkafka=lambda: "2.10.1"))


def test_kafka_clients_too_old_for_gcn_fail_before_any_connection(broker, topic, loopback, monkeypatch, capsys,
                                                                    tmp_path) -> None:
    """The service refuses to start on GCN with clients that lose the token; preflight must say so too."""
    _old_kafka_clients(monkeypatch)
    tokens = TokenEndpoint(loopback, "gcn-client-id", "gcn-S3cret-value")
    from mushrooms.tool.preflight import kafka_check

    over = {"bootstrap.servers": broker.bootstrap, "security.protocol": "sasl_plaintext",
            "sasl.oauthbearer.token.endpoint.url": tokens.url}
    status, _, reason = kafka_check(KafkaConfig(topics=(topic,)), 3,
                                    Credentials("gcn-client-id", "gcn-S3cret-value", "test"), over)
    assert status == "FAIL", reason
    assert "gcn-kafka 0.3.3 (needs >= 0.3.4)" in reason and "confluent-kafka 2.10.1 (needs >= 2.11.0)" in reason
    assert "lose the GCN token" in reason and tokens.asked == 0  # said before anything was tried
    # a local broker needs no token: as the service, a warning, not a failure
    cfg = _config(tmp_path, broker.bootstrap, topic)
    code, lines, text = _preflight(capsys, "--config", str(cfg), "--timeout", "10")
    assert code == 0 and lines["kafka"][0] == "ok", text
    assert "gcn-kafka 0.3.3 (needs >= 0.3.4)" in lines["kafka"][1], text


@pytest.mark.parametrize("url, why", [
    (f"https://ops:pw@hooks.example/services/{HOOK_SECRET}", "it must not carry user:password@"),
    (f"https://hooks.example:0/services/{HOOK_SECRET}", "its port is not a number from 1 to 65535"),
    (f"https://hooks.example/services/T000 /{HOOK_SECRET}", "it contains spaces"),  # a space inside: not stripped
    (f"https://[fe80::1/services/{HOOK_SECRET}", "its host is not a valid IPv6 literal in brackets"),
])
def test_the_webhook_url_is_checked_as_the_service_checks_it_before_any_test_message(
        broker, topic, loopback, tmp_path, monkeypatch, capsys, url, why) -> None:
    """The service refuses these URLs at start (``ops/webhook_url.py``); preflight passed them or said less."""
    loopback.expect_request(f"/services/{HOOK_SECRET}", method="POST").respond_with_data("ok")
    monkeypatch.setenv("MUSHROOMS_NOTIFY_URL", url)
    cfg = _config(tmp_path, broker.bootstrap, topic, '[notify]\ntarget = "slack"\n')
    for asked in ((), ("--notify-test",)):  # the URL is checked whether or not a test message is asked for
        code, lines, text = _preflight(capsys, "--config", str(cfg), *asked, "--timeout", "5")
        assert code == 1 and lines["webhook"][0] == "FAIL", text
        assert f"cannot be used: {why}" in lines["webhook"][1], text
        assert lines["webhook"][1].startswith("the webhook URL from env:MUSHROOMS_NOTIFY_URL"), text
        assert HOOK_SECRET not in text and "ops:pw" not in text
    assert not [r for r, _ in loopback.log if r.path.startswith("/services/")]  # no test message was sent


def test_the_skyportal_of_submit_parts_takes_its_own_token(broker, topic, loopback, tmp_path, monkeypatch,
                                                           capsys) -> None:
    """``[submit_parts]`` (issue 53): skipped when off; its token (``MUSHROOMS_SKYPORTAL_TOKEN``) checked when on."""
    def profile(request: Request) -> Response:
        if request.headers.get("Authorization") != "token parts-tok-1":
            return Response(json.dumps({"status": "error", "message": "Unauthorized"}), 401,
                            content_type="application/json")
        return Response(json.dumps({"status": "success", "data": {"username": "winter-bot",
                                                                  "permissions": ["Manage observation plans"]}}),
                        200, content_type="application/json")

    loopback.expect_request("/api/internal/profile", method="GET").respond_with_handler(profile)
    cfg = _config(tmp_path, broker.bootstrap, topic, "")
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert lines["submission_parts"][0] == "skip" and "enabled = false" in lines["submission_parts"][1], text
    cfg = _config(tmp_path, broker.bootstrap, topic, f'[submit_parts]\nenabled = true\nurl = '
                  f'"{loopback.url_for("/").rstrip("/")}"\nallocations = {{ winter = 7 }}\n')
    monkeypatch.delenv("MUSHROOMS_SKYPORTAL_TOKEN", raising=False)
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 1 and "MUSHROOMS_SKYPORTAL_TOKEN" in lines["submission_parts"][1], text
    monkeypatch.setenv("MUSHROOMS_SKYPORTAL_TOKEN", "parts-tok-1")
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 0 and lines["submission_parts"][0] == "ok", text
    assert "user winter-bot, may manage observation plans); allocations: winter 7" in lines["submission_parts"][1]
    monkeypatch.setenv("MUSHROOMS_SKYPORTAL_TOKEN", "parts-tok-2")
    code, lines, text = _preflight(capsys, "--config", str(cfg))
    assert code == 1 and "token refused" in lines["submission_parts"][1] and "parts-tok-2" not in text
