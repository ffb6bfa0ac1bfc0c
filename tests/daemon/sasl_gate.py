"""GCN's login on loopback, for librdkafka's mock cluster (tests only): an OIDC token endpoint and a SASL/OAUTHBEARER
front door.

librdkafka's mock cluster answers no SASL request: its request handlers
(``src/rdkafka_mock_handlers.c``, the table ``rd_kafka_mock_api_handlers``,
librdkafka 4c3b017c3) have no SaslHandshake (17) nor SaslAuthenticate (36),
and a client with ``security.protocol = sasl_plaintext`` stops at "SASL
Handshake not supported by broker".  GCN checks credentials in two places:
its OIDC token endpoint (``https://auth.<domain>/oauth2/token``,
client-credentials grant with the client id and secret as HTTP basic auth)
issues a token only for good ones, and its brokers take only a valid token
(SASL/OAUTHBEARER, re-authenticated before the token expires).

:class:`TokenEndpoint` is that endpoint (pytest-httpserver): a JWT of a given
lifetime for one client id and secret.  :class:`SaslGate` sits in front of the
mock broker and does what a Kafka broker with OAUTHBEARER and KIP-368
re-authentication does, no more:

- it offers SaslHandshake (v0-1) and SaslAuthenticate (v0-1) in its ApiVersions answer;
- it reads the client's ``auth=Bearer <JWT>`` and refuses a token that is malformed, has no
  ``sub``, has expired, or (given a :class:`TokenEndpoint`) was not issued by it, with
  ``{"status":"invalid_token"}`` (error 58, as GCN's brokers say);
- it grants a session as long as the token's remaining lifetime (``session_lifetime_ms``) and
  closes a connection whose session has run out without re-authentication at its next request;
- every other request is relayed to the mock broker, with the broker address in Metadata and
  FindCoordinator answers replaced by its own (so that the client never goes round it).

Counters (``authentications``, ``reauthentications``, ``refused``, ``expired``) say what happened.
The client under test is librdkafka itself, configured by gcn-kafka as for GCN
(``sasl.oauthbearer.method = oidc``), with only the token endpoint's URL, the bootstrap address
and ``sasl_plaintext`` laid over.  The protocol is written here from the Kafka protocol guide;
one mock broker only.
"""

from __future__ import annotations

import base64
import json
import socket
import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Any

__all__ = ["SaslGate", "TokenEndpoint", "unsecured_jwt"]

API_METADATA, API_FIND_COORDINATOR, API_SASL_HANDSHAKE, API_API_VERSIONS, API_SASL_AUTHENTICATE = 3, 10, 17, 18, 36
SASL_AUTHENTICATION_FAILED = 58
INVALID_TOKEN = '{"status":"invalid_token"}'


def unsecured_jwt(subject: str, lifetime_s: float, now: float | None = None) -> str:
    """A JWT with ``sub`` and ``exp`` (s since the epoch) and no real signature: what the gate checks."""
    def b64(d: dict[str, Any]) -> str:
        return base64.urlsafe_b64encode(json.dumps(d).encode()).rstrip(b"=").decode()

    now = time.time() if now is None else now
    return f"{b64({'alg': 'none', 'typ': 'JWT'})}.{b64({'sub': subject, 'exp': int(now + lifetime_s)})}.c2ln"


def _token_expiry(auth: bytes) -> tuple[float | None, str, str]:
    """(exp, subject, token) of the client-first message ``n,,\\x01auth=Bearer T\\x01\\x01``; exp None if unreadable."""
    token = ""
    try:
        fields = dict(kv.split("=", 1) for kv in auth.decode().split("\x01")[1:] if "=" in kv)
        token = fields["auth"].split(" ", 1)[1].strip()
        payload = token.split(".")[1]
        claims = json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))
        return float(claims["exp"]), str(claims["sub"]), token
    except (KeyError, IndexError, ValueError, TypeError):
        return None, "", token


class TokenEndpoint:
    """An OIDC client-credentials token endpoint on a pytest-httpserver: a JWT for one client id and secret.

    Parameters
    ----------
    server : pytest_httpserver.HTTPServer
        Serves ``POST /oauth2/token`` (:attr:`url`).
    client_id, client_secret : str
        The one pair it takes (HTTP basic auth, ``grant_type=client_credentials``); anything else is
        refused with 400 ``{"error":"invalid_client"}``.
    lifetime_s : float
        Lifetime (s) of the tokens it issues (:func:`unsecured_jwt`).

    Attributes
    ----------
    issued : set of str
        The tokens it issued (a :class:`SaslGate` given this endpoint takes only these).
    asked, refused : int
        Requests, and requests refused.
    """

    def __init__(self, server: Any, client_id: str, client_secret: str, lifetime_s: float = 3600.0) -> None:
        self.client_id, self.client_secret, self.lifetime_s = client_id, client_secret, float(lifetime_s)
        self.issued: set[str] = set()
        self.asked = self.refused = 0
        server.expect_request("/oauth2/token", method="POST").respond_with_handler(self._token)
        self.url = server.url_for("/oauth2/token")

    def _token(self, request: Any) -> Any:
        from werkzeug.wrappers import Response

        self.asked += 1
        good = "Basic " + base64.b64encode(f"{self.client_id}:{self.client_secret}".encode()).decode()
        if request.headers.get("Authorization") != good or request.form.get("grant_type") != "client_credentials":
            self.refused += 1
            return Response('{"error":"invalid_client"}', status=400, content_type="application/json")
        token = unsecured_jwt(self.client_id, self.lifetime_s)
        self.issued.add(token)
        body = {"access_token": token, "token_type": "Bearer", "expires_in": int(self.lifetime_s)}
        return Response(json.dumps(body), status=200, content_type="application/json")


# ---------------------------------------------------------------- wire helpers


class Reader:
    """Cursor over one frame's bytes."""

    def __init__(self, data: bytes, pos: int = 0) -> None:
        self.data, self.pos = data, pos

    def take(self, n: int) -> bytes:
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def i16(self) -> int:
        return struct.unpack(">h", self.take(2))[0]

    def i32(self) -> int:
        return struct.unpack(">i", self.take(4))[0]

    def uvarint(self) -> int:
        shift = value = 0
        while True:
            b = self.take(1)[0]
            value |= (b & 0x7F) << shift
            if not b & 0x80:
                return value
            shift += 7

    def string(self, compact: bool) -> str | None:
        n = self.uvarint() - 1 if compact else self.i16()
        return None if n < 0 else self.take(n).decode()

    def tags(self) -> bytes:
        """Skip a tagged-field section; its raw bytes."""
        start = self.pos
        for _ in range(self.uvarint()):
            self.uvarint()
            self.take(self.uvarint())
        return self.data[start:self.pos]


def uvarint(n: int) -> bytes:
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def string(s: str | None, compact: bool) -> bytes:
    if s is None:
        return uvarint(0) if compact else struct.pack(">h", -1)
    raw = s.encode()
    return (uvarint(len(raw) + 1) if compact else struct.pack(">h", len(raw))) + raw


def flexible(api: int, version: int) -> bool:
    """Whether a request/response of this API version uses the flexible (tagged-field) encoding."""
    return version >= {API_METADATA: 9, API_FIND_COORDINATOR: 3, API_API_VERSIONS: 3}.get(api, 99)


def recv_frame(sock: socket.socket) -> bytes | None:
    head = _recv_exact(sock, 4)
    if head is None:
        return None
    return _recv_exact(sock, struct.unpack(">i", head)[0])


def _recv_exact(sock: socket.socket, n: int) -> bytes | None:
    buf = bytearray()
    while len(buf) < n:
        try:
            chunk = sock.recv(n - len(buf))
        except OSError:
            return None
        if not chunk:
            return None
        buf += chunk
    return bytes(buf)


# ---------------------------------------------------------------- answers rewritten


def rewrite_api_versions(body: bytes, version: int) -> bytes:
    """The broker's ApiVersions answer plus SaslHandshake 0-1 and SaslAuthenticate 0-1."""
    r = Reader(body)
    error = r.i16()
    if error:  # an unsupported version: the client asks again with one the broker named
        return body
    compact = flexible(API_API_VERSIONS, version)
    n = r.uvarint() - 1 if compact else r.i32()
    entries = []
    for _ in range(n):
        key, lo, hi = r.i16(), r.i16(), r.i16()
        tags = r.tags() if compact else b""
        if key not in (API_SASL_HANDSHAKE, API_SASL_AUTHENTICATE):
            entries.append(struct.pack(">hhh", key, lo, hi) + tags)
    for key in (API_SASL_HANDSHAKE, API_SASL_AUTHENTICATE):
        entries.append(struct.pack(">hhh", key, 0, 1) + (uvarint(0) if compact else b""))
    count = uvarint(len(entries) + 1) if compact else struct.pack(">i", len(entries))
    return struct.pack(">h", 0) + count + b"".join(entries) + body[r.pos:]


def rewrite_metadata(body: bytes, version: int, port: int) -> bytes:
    """Every broker of a Metadata answer moved to 127.0.0.1:``port``; the rest copied."""
    r = Reader(body)
    compact = flexible(API_METADATA, version)
    head = r.take(4) if version >= 3 else b""  # throttle_time_ms
    n = r.uvarint() - 1 if compact else r.i32()
    out = [head, uvarint(n + 1) if compact else struct.pack(">i", n)]
    for _ in range(n):
        node = r.i32()
        r.string(compact)
        r.i32()
        rack = r.string(compact) if version >= 1 else None
        tags = r.tags() if compact else b""
        out.append(struct.pack(">i", node) + string("127.0.0.1", compact) + struct.pack(">i", port)
                   + (string(rack, compact) if version >= 1 else b"") + tags)
    return b"".join(out) + body[r.pos:]


def rewrite_find_coordinator(body: bytes, version: int, port: int) -> bytes:
    """The coordinator of a FindCoordinator answer (v0-3) moved to 127.0.0.1:``port``."""
    r = Reader(body)
    compact = flexible(API_FIND_COORDINATOR, version)
    head = r.take(4) if version >= 1 else b""
    error = r.take(2)
    msg = string(r.string(compact), compact) if version >= 1 else b""
    node = r.take(4)
    r.string(compact)
    r.i32()
    return head + error + msg + node + string("127.0.0.1", compact) + struct.pack(">i", port) + body[r.pos:]


# ---------------------------------------------------------------- the gate


@dataclass
class _Session:
    """One client connection's authentication state."""

    authenticated: bool = False
    expires: float = 0.0
    pending: dict[int, tuple[int, int]] = field(default_factory=dict)  # correlation id -> (api, version)


class SaslGate:
    """OAUTHBEARER front door of one mock broker; ``bootstrap`` is its ``127.0.0.1:PORT``.

    Parameters
    ----------
    upstream : str
        ``HOST:PORT`` of the mock broker.
    tokens : TokenEndpoint, optional
        Take only the tokens it issued (GCN's brokers take only tokens of GCN's endpoint); without
        it, any well-formed unexpired JWT with a ``sub``.
    """

    def __init__(self, upstream: str, tokens: TokenEndpoint | None = None) -> None:
        host, port = upstream.rsplit(":", 1)
        self.upstream = (host, int(port))
        self.tokens = tokens
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self.bootstrap = f"127.0.0.1:{self.port}"
        self.lock = threading.Lock()
        self.authentications = self.reauthentications = self.refused = self.expired = 0
        self.subjects: set[str] = set()
        self._closed = False
        threading.Thread(target=self._accept, daemon=True, name="sasl-gate").start()

    def close(self) -> None:
        self._closed = True
        self._server.close()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._server.accept()
            except OSError:
                return
            threading.Thread(target=self._serve, args=(client,), daemon=True, name="sasl-gate-conn").start()

    def _serve(self, client: socket.socket) -> None:
        upstream = socket.create_connection(self.upstream)
        session, wlock = _Session(), threading.Lock()
        threading.Thread(target=self._relay_back, args=(upstream, client, session, wlock), daemon=True).start()
        try:
            while (frame := recv_frame(client)) is not None:
                if not self._request(frame, client, upstream, session, wlock):
                    break
        finally:
            for s in (client, upstream):
                try:
                    s.close()
                except OSError:
                    pass

    def _request(self, frame: bytes, client: socket.socket, upstream: socket.socket, session: _Session,
                 wlock: threading.Lock) -> bool:
        """Answer or relay one request; False closes the connection."""
        r = Reader(frame)
        api, version, corr = r.i16(), r.i16(), r.i32()
        r.string(False)  # client id (request header v1: SASL requests are never flexible)
        if api == API_SASL_HANDSHAKE:
            body = struct.pack(">h", 0) + struct.pack(">i", 1) + string("OAUTHBEARER", False)
            _send(client, wlock, corr, body)
            return True
        if api == API_SASL_AUTHENTICATE:
            return self._authenticate(r.take(r.i32()), version, corr, client, session, wlock)
        if api != API_API_VERSIONS:
            if not session.authenticated:
                return False  # a broker closes a connection that talks before it authenticates
            if time.time() >= session.expires:
                with self.lock:
                    self.expired += 1
                return False  # KIP-368: the session ran out without re-authentication
        session.pending[corr] = (api, version)
        upstream.sendall(struct.pack(">i", len(frame)) + frame)
        return True

    def _authenticate(self, auth: bytes, version: int, corr: int, client: socket.socket, session: _Session,
                      wlock: threading.Lock) -> bool:
        exp, subject, token = _token_expiry(auth)
        now = time.time()
        unknown = self.tokens is not None and token not in self.tokens.issued
        if exp is None or not subject or exp <= now or unknown:
            with self.lock:
                self.refused += 1
            body = struct.pack(">h", SASL_AUTHENTICATION_FAILED) + string(INVALID_TOKEN, False) + struct.pack(">i", 0)
            _send(client, wlock, corr, body + (struct.pack(">q", 0) if version >= 1 else b""))
            return True  # the client closes; a broker would too after the answer
        with self.lock:
            if session.authenticated:
                self.reauthentications += 1
            else:
                self.authentications += 1
            self.subjects.add(subject)
        session.authenticated, session.expires = True, exp
        lifetime_ms = int((exp - now) * 1000)
        body = struct.pack(">h", 0) + string(None, False) + struct.pack(">i", 0)
        _send(client, wlock, corr, body + (struct.pack(">q", lifetime_ms) if version >= 1 else b""))
        return True

    def _relay_back(self, upstream: socket.socket, client: socket.socket, session: _Session,
                    wlock: threading.Lock) -> None:
        while (frame := recv_frame(upstream)) is not None:
            corr = struct.unpack(">i", frame[:4])[0]
            api, version = session.pending.pop(corr, (-1, 0))
            head_len = 4
            if api != API_API_VERSIONS and flexible(api, version):  # response header v1: tagged fields follow
                head_len += len(Reader(frame, 4).tags())
            head, body = frame[:head_len], frame[head_len:]
            if api == API_API_VERSIONS:
                body = rewrite_api_versions(body, version)
            elif api == API_METADATA:
                body = rewrite_metadata(body, version, self.port)
            elif api == API_FIND_COORDINATOR and version <= 3:
                body = rewrite_find_coordinator(body, version, self.port)
            with wlock:
                try:
                    client.sendall(struct.pack(">i", len(head) + len(body)) + head + body)
                except OSError:
                    return
        try:
            client.close()
        except OSError:
            pass


def _send(client: socket.socket, wlock: threading.Lock, corr: int, body: bytes) -> None:
    """One answer of the gate's own (response header v0: SASL answers are never flexible)."""
    with wlock:
        client.sendall(struct.pack(">ii", len(body) + 4, corr) + body)
