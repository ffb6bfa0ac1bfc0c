"""Issue 52, finding 10: the operator's check (``mushrooms preflight``) on loopback, good and bad.

1. ``mushrooms preflight`` (the command, a process of its own) against librdkafka's mock cluster
   (``[kafka] bootstrap``) and a Kowalski stand-in (pytest-httpserver) with a good token, a bad
   token and none; then with a topic that does not exist and a broker that does not answer.
2. The GCN credentials: the mock cluster speaks no SASL, so the kafka check (the function the
   command calls, ``mushrooms.tool.preflight.kafka_check``) is run through
   ``tests/daemon/sasl_gate.py``: an OIDC token endpoint and a SASL/OAUTHBEARER login in front of
   the mock cluster; librdkafka is configured by gcn-kafka as for GCN, only the token endpoint's
   URL and the broker's address point at loopback.  Good secret, bad secret, a token the endpoint
   never issued.

    python benchmarks/attacks/preflight_loopback.py > benchmarks/results/attacks/trusted_round5/operator/preflight_loopback.txt
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(REPO), str(REPO / "tests" / "daemon")]

TOKEN = "kowalski-G00D-t0ken-4f1c"


def kowalski(server) -> None:
    from werkzeug import Request, Response

    def answer(request: Request) -> Response:
        auth = request.headers.get("Authorization")
        if auth != f"Bearer {TOKEN}":
            msg, code = ("auth required", 401) if auth is None else ("token is invalid", 400)
            return Response(json.dumps({"status": "error", "message": msg}), code, content_type="application/json")
        return Response(json.dumps({"status": "success", "message": "retrieved", "data": []}), 200,
                        content_type="application/json")

    server.expect_request("/api/triggers/ztf", method="GET").respond_with_handler(answer)


def preflight(tmp: Path, bootstrap: str, topic: str, url: str, token: str | None, timeout: str = "10") -> None:
    cfg = tmp / "config.toml"
    cfg.write_text(f'[daemon]\nstate_path = "{tmp}/state/mushrooms-state.sqlite"\n[kafka]\nbootstrap = "{bootstrap}"\n'
                   f'topics = ["{topic}"]\nassignment = "manual"\n[outbound]\ndirectory = "{tmp}/outbox"\n'
                   f'[submit]\ntarget = "kowalski"\nurl = "{url}"\n')
    env = {k: v for k, v in os.environ.items() if k != "MUSHROOMS_SUBMIT_TOKEN"} | {"PYTHONPATH": str(REPO)}
    if token is not None:
        env["MUSHROOMS_SUBMIT_TOKEN"] = token
    cmd = [sys.executable, "-m", "mushrooms.cli", "preflight", "--config", str(cfg), "--timeout", timeout]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp, timeout=300)
    shown = "none" if token is None else f"{token[:4]}... ({'good' if token == TOKEN else 'bad'})"
    print(f"$ MUSHROOMS_SUBMIT_TOKEN=<{shown}> mushrooms preflight --config config.toml --timeout {timeout}"
          f"   # broker {bootstrap}, topic {topic}")
    print(out.stdout.rstrip())
    print(f"[exit {out.returncode}; stderr {len(out.stderr.splitlines())} line(s), "
          f"token in output: {bool(token) and token in out.stdout + out.stderr}]\n")


def main() -> int:
    from contract_servers import loopback_server
    from sasl_gate import SaslGate, TokenEndpoint

    from mushrooms.daemon.credentials import Credentials
    from mushrooms.daemon.settings import KafkaConfig
    from mushrooms.tool.loopback_broker import LoopbackBroker
    from mushrooms.tool.preflight import kafka_check

    print(f"load: {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1/5/15 min)\n")
    broker = LoopbackBroker()
    broker.ensure_topic("igwn.gwalert")
    server = loopback_server()
    kowalski(server)
    url = server.url_for("/").rstrip("/")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        print("## 1. the command: local broker, Kowalski stand-in\n")
        for token in (TOKEN, "expired-tok-9d2e", None):
            preflight(tmp, broker.bootstrap, "igwn.gwalert", url, token)
        preflight(tmp, broker.bootstrap, "igwn.gwalert.typo", url, TOKEN)
        preflight(tmp, "127.0.0.1:9", "igwn.gwalert", url, TOKEN, timeout="3")
    print("## 2. GCN credentials: OIDC token endpoint + SASL/OAUTHBEARER login in front of the mock cluster\n")
    tokens = TokenEndpoint(server, "gcn-client-id", "gcn-S3cret-value")
    gate = SaslGate(broker.bootstrap, tokens)
    over = {"bootstrap.servers": gate.bootstrap, "security.protocol": "sasl_plaintext",
            "sasl.oauthbearer.token.endpoint.url": tokens.url}
    kafka = KafkaConfig(topics=("igwn.gwalert",))
    unsigned = {**over, "sasl.oauthbearer.method": "default", "enable.sasl.oauthbearer.unsecure.jwt": True,
                "sasl.oauthbearer.config": "principal=gcn-client-id"}
    for what, secret, extra in (("good secret", "gcn-S3cret-value", over), ("bad secret", "wrong-secret-77", over),
                                ("a token the endpoint never issued", "gcn-S3cret-value", unsigned)):
        status, name, reason = kafka_check(kafka, 15, Credentials("gcn-client-id", secret, "test"), extra)
        print(f"{what}:\n{status:<4} {name}: {reason}")
        print(f"[secret in the line: {secret in reason}]\n")
    print(f"token endpoint asked {tokens.asked} time(s), refused {tokens.refused}; SASL logins at the gate: "
          f"{gate.authentications} accepted, {gate.refused} refused")
    gate.close()
    server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
