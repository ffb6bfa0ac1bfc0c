"""The loop's secrets: never in a configured URL, no form of them in what is logged or raised."""

from __future__ import annotations

import base64
import json
import subprocess
import sys
from pathlib import Path

import pytest
from astropy.time import Time
from werkzeug.wrappers import Response

from mushrooms.daemon.loop.fetch import ExecutedReader, FetchError
from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.handlers.executed_source import parse_executed_source


PASSWORD = "hunter2-Zq9"
NIGHT = (Time("2025-05-14T03:00:00", scale="utc"), Time("2025-05-14T06:00:00", scale="utc"))


@pytest.mark.parametrize("spec", [f"skyportal:https://ops:{PASSWORD}@fritz.example.org",
                                  f"depot:https://ztfuser:{PASSWORD}@ztfweb.example.org/ztf/depot",
                                  "depot:http://ztfuser@127.0.0.1:9/depot"])
def test_a_loop_url_with_credentials_is_refused_without_showing_them(spec):
    with pytest.raises(ValueError) as err:
        LoopConfig(executed_source=spec)
    message = str(err.value)
    assert "must not carry credentials" in message and "MUSHROOMS_EXECUTED_TOKEN" in message
    assert PASSWORD not in message and "ztfuser" not in message and "ops:" not in message


def test_an_error_answer_echoing_the_basic_header_is_redacted(loopback):
    server = loopback
    def echo(request):
        return Response(json.dumps({"message": f"denied: Authorization: {request.headers.get('Authorization')}"}),
                        status=403, content_type="application/json")

    server.expect_request("/depot/20250514/ztf_recentproc_20250514.json").respond_with_handler(echo)
    server.expect_request("/depot/20250513/ztf_recentproc_20250513.json").respond_with_handler(echo)
    token = f"ztfuser:{PASSWORD}"
    reader = ExecutedReader(parse_executed_source(f"depot:{server.url_for('/depot')}"), token, timeout_s=5.0)
    with pytest.raises(FetchError) as err:
        reader.read(*NIGHT)
    basic = base64.b64encode(token.encode()).decode()
    message = str(err.value)
    assert "answered 403" in message and "***" in message
    assert basic not in message and PASSWORD not in message


def test_redact_blanks_every_form_of_the_secret():
    from mushrooms.handlers.secret_text import redact

    token = f"u:{PASSWORD}"
    text = (f"raw {token} basic {base64.b64encode(token.encode()).decode()} url http://u:{PASSWORD}@h/x "
            f"quoted u%3A{PASSWORD}")
    out = redact(text, token)
    assert PASSWORD not in out and base64.b64encode(token.encode()).decode() not in out
    assert out.count("***") == 4


def test_queue_list_refuses_a_url_with_a_password(tmp_path):
    import mushrooms

    code = str(Path(mushrooms.__file__).resolve().parents[1])  # the package under test, from any directory
    r = subprocess.run([sys.executable, "-m", "mushrooms.cli", "queue", "list", "--url",
                        f"http://u:{PASSWORD}@127.0.0.1:9/"], capture_output=True, text=True, timeout=120,
                       cwd=tmp_path, env={"PATH": "/usr/bin:/bin", "MUSHROOMS_SUBMIT_TOKEN": "t0ken-abc", "PYTHONPATH": code})
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "must not carry credentials" in r.stderr
    assert PASSWORD not in r.stdout + r.stderr
