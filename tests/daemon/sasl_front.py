"""A SASL/OAUTHBEARER login in front of librdkafka's mock cluster, and an OIDC token endpoint: GCN's login on loopback.

librdkafka's mock cluster speaks no SASL: its request handlers
(``src/rdkafka_mock_handlers.c``, the table ``rd_kafka_mock_api_handlers``,
librdkafka 4c3b017c3) have no SaslHandshake (17) nor SaslAuthenticate (36),
and a client with ``security.protocol = sasl_plaintext`` stops at "SASL
Handshake not supported by broker".  So it cannot tell good credentials
from bad.  GCN checks them in two places: its OIDC token endpoint
(``https://auth.<domain>/oauth2/token``, client-credentials grant with the
client id and secret as HTTP basic auth) issues a token only for good ones,
and its brokers take only a token it issued (SASL/OAUTHBEARER).

:class:`SaslFront` is that broker side: it listens on loopback, answers
SaslHandshake and SaslAuthenticate itself (accepting only the tokens the
:class:`TokenEndpoint` issued), adds the two APIs to the mock's ApiVersions
answer, and after a good login relays the Kafka protocol to the mock cluster
unchanged, except that the mock broker's port in Metadata answers becomes
the front's (so the client's next connections come through the login too).
The client under test is librdkafka itself, configured by gcn-kafka exactly
as for GCN (``sasl.oauthbearer.method = oidc``), with only the token
endpoint's URL, the bootstrap address and ``sasl_plaintext`` laid over.
"""

from __future__ import annotations

import base64
import json
import secrets
import socket
import struct
import threading
import time
from typing import Any

from werkzeug import Request, Response

SASL_HANDSHAKE, SASL_AUTHENTICATE, API_VERSIONS = 17, 36, 18
REWRITTEN = {3, 10}  # Metadata and FindCoordinator answers name brokers


def _read_exact(sock: socket.socket, n: int) -> bytes:
    data = bytearray()
    while len(data) < n:
        piece = sock.recv(n - len(data))
        if not piece:
            raise ConnectionError("closed")
        data += piece
    return bytes(data)


def _frame(sock: socket.socket) -> bytes:
    (size,) = struct.unpack(">i", _read_exact(sock, 4))
    return _read_exact(sock, size)


def _send(sock: socket.socket, payload: bytes) -> None:
    sock.sendall(struct.pack(">i", len(payload)) + payload)


class TokenEndpoint:
    """An OIDC client-credentials token endpoint (pytest-httpserver): a JWT-shaped token for one client id and secret."""

    def __init__(self, server: Any, client_id: str, client_secret: str) -> None:
        self.server, self.client_id, self.client_secret = server, client_id, client_secret
        self.issued: set[str] = set()
        self.asked = 0
        server.expect_request("/oauth2/token", method="POST").respond_with_handler(self._token)
        self.url = server.url_for("/oauth2/token")

    def _token(self, request: Request) -> Response:
        self.asked += 1
        good = "Basic " + base64.b64encode(f"{self.client_id}:{self.client_secret}".encode()).decode()
        if request.headers.get("Authorization") != good or "client_credentials" not in request.get_data(as_text=True):
            return Response('{"error":"invalid_client"}', status=400, content_type="application/json")

        def part(d: dict) -> str:
            return base64.urlsafe_b64encode(json.dumps(d).encode()).rstrip(b"=").decode()

        now = int(time.time())
        token = f"{part({'alg': 'none'})}.{part({'sub': self.client_id, 'iat': now, 'exp': now + 3600})}." \
                f"{secrets.token_hex(8)}"
        self.issued.add(token)
        body = {"access_token": token, "token_type": "Bearer", "expires_in": 3600}
        return Response(json.dumps(body), status=200, content_type="application/json")


class SaslFront:
    """SASL/OAUTHBEARER login on loopback in front of the mock broker ``upstream`` (``HOST:PORT``)."""

    def __init__(self, upstream: str, tokens: TokenEndpoint) -> None:
        host, port = upstream.rsplit(":", 1)
        self.upstream = (host, int(port))
        self.tokens = tokens
        self.logins: list[bool] = []
        self._listen = socket.create_server(("127.0.0.1", 0))
        self.port = self._listen.getsockname()[1]
        self.bootstrap = f"127.0.0.1:{self.port}"
        self._closed = False
        threading.Thread(target=self._accept, daemon=True).start()

    def close(self) -> None:
        self._closed = True
        self._listen.close()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._listen.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(client,), daemon=True).start()

    def _serve(self, client: socket.socket) -> None:
        up = socket.create_connection(self.upstream)
        asked: dict[int, tuple[int, int]] = {}  # correlation id -> (api key, version)
        threading.Thread(target=self._answers, args=(up, client, asked), daemon=True).start()
        authed = False
        try:
            while True:
                frame = _frame(client)
                key, version, corr = struct.unpack(">hhi", frame[:8])
                (id_len,) = struct.unpack(">h", frame[8:10])
                body = frame[10 + max(id_len, 0):]
                if key == SASL_HANDSHAKE:
                    (n,) = struct.unpack(">h", body[:2])
                    mech = body[2:2 + n]
                    err = 0 if mech == b"OAUTHBEARER" else 33  # UNSUPPORTED_SASL_MECHANISM
                    _send(client, struct.pack(">ihih", corr, err, 1, 11) + b"OAUTHBEARER")
                elif key == SASL_AUTHENTICATE:
                    (n,) = struct.unpack(">i", body[:4])
                    authed = self._login(body[4:4 + n])
                    self._auth_answer(client, corr, version, authed)
                    if not authed:
                        return
                elif key != API_VERSIONS and not authed:
                    return  # no request before the login
                else:
                    asked[corr] = (key, version)
                    _send(up, frame)
        except (ConnectionError, OSError, struct.error):
            pass
        finally:
            client.close()
            up.close()

    def _login(self, auth: bytes) -> bool:
        """RFC 7628's client first message: ``n,,\\x01auth=Bearer <token>\\x01\\x01``."""
        fields = dict(f.split("=", 1) for f in auth.decode("utf-8", "replace").split("\x01") if "=" in f)
        token = fields.get("auth", "").removeprefix("Bearer ").strip()
        ok = token in self.tokens.issued
        self.logins.append(ok)
        return ok

    @staticmethod
    def _auth_answer(client: socket.socket, corr: int, version: int, ok: bool) -> None:
        msg = b"" if ok else b"invalid token"
        out = struct.pack(">ih", corr, 0 if ok else 58)  # 58: SASL_AUTHENTICATION_FAILED
        out += struct.pack(">h", -1) if ok else struct.pack(">h", len(msg)) + msg
        out += struct.pack(">i", 0)  # no server message
        if version >= 1:
            out += struct.pack(">q", 3_600_000 if ok else 0)
        _send(client, out)

    def _answers(self, up: socket.socket, client: socket.socket, asked: dict[int, tuple[int, int]]) -> None:
        mock_port = struct.pack(">i", self.upstream[1])
        front_port = struct.pack(">i", self.port)
        try:
            while True:
                frame = _frame(up)
                (corr,) = struct.unpack(">i", frame[:4])
                key, version = asked.pop(corr, (-1, -1))
                if key == API_VERSIONS and version <= 2:
                    frame = self._with_sasl(frame, version)
                elif key in REWRITTEN:
                    for host in (b"\x0a127.0.0.1", b"\x00\x09127.0.0.1"):  # compact / classic string
                        frame = frame.replace(host + mock_port, host + front_port)
                _send(client, frame)
        except (ConnectionError, OSError, struct.error):
            client.close()

    @staticmethod
    def _with_sasl(frame: bytes, version: int) -> bytes:
        """The mock's ApiVersions answer (v0-v2) with SaslHandshake v0-1 and SaslAuthenticate v0-1 added."""
        corr, err, count = struct.unpack(">ihi", frame[:10])
        if err != 0:
            return frame
        entries = frame[10:10 + 6 * count]
        rest = frame[10 + 6 * count:]
        added = struct.pack(">hhh", SASL_HANDSHAKE, 0, 1) + struct.pack(">hhh", SASL_AUTHENTICATE, 0, 1)
        return struct.pack(">ihi", corr, err, count + 2) + entries + added + rest
