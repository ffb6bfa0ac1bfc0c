"""A SASL/OAUTHBEARER front door for librdkafka's mock cluster, on loopback (tests only).

The mock cluster answers no SASL request (its handler table has no SaslHandshake or
SaslAuthenticate), so a client configured for GCN's OAUTHBEARER cannot talk to it directly.
:class:`SaslGate` sits in front of it and does what a Kafka broker with OAUTHBEARER and KIP-368
re-authentication does, no more:

- it offers SaslHandshake (v0-1) and SaslAuthenticate (v0-1) in its ApiVersions answer;
- it reads the client's ``auth=Bearer <JWT>`` and refuses a token that is malformed, has no
  ``sub`` or has expired with ``{"status":"invalid_token"}`` (error 58, as GCN's brokers say);
- it grants a session as long as the token's remaining lifetime (``session_lifetime_ms``) and
  closes a connection whose session has run out without re-authentication at its next request;
- every other request is relayed to the mock broker, with the broker address in Metadata and
  FindCoordinator answers replaced by its own (so that the client never goes round it).

Counters (``authentications``, ``reauthentications``, ``refused``, ``expired``) say what happened.
The protocol is written here from the Kafka protocol guide; one mock broker only.
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

__all__ = ["SaslGate", "unsecured_jwt"]

API_METADATA, API_FIND_COORDINATOR, API_SASL_HANDSHAKE, API_API_VERSIONS, API_SASL_AUTHENTICATE = 3, 10, 17, 18, 36
SASL_AUTHENTICATION_FAILED = 58
INVALID_TOKEN = '{"status":"invalid_token"}'


def unsecured_jwt(subject: str, lifetime_s: float, now: float | None = None) -> str:
    """A JWT with ``sub`` and ``exp`` (s since the epoch) and no real signature: what the gate checks."""
    def b64(d: dict[str, Any]) -> str:
        return base64.urlsafe_b64encode(json.dumps(d).encode()).rstrip(b"=").decode()

    now = time.time() if now is None else now
    return f"{b64({'alg': 'none', 'typ': 'JWT'})}.{b64({'sub': subject, 'exp': int(now + lifetime_s)})}.c2ln"


def _token_expiry(auth: bytes) -> tuple[float | None, str]:
    """(exp, subject) of the client-first message ``n,,\\x01auth=Bearer T\\x01\\x01``; exp None if unreadable."""
    try:
        fields = dict(kv.split("=", 1) for kv in auth.decode().split("\x01")[1:] if "=" in kv)
        token = fields["auth"].split(" ", 1)[1]
        payload = token.split(".")[1]
        claims = json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))
        return float(claims["exp"]), str(claims["sub"])
    except (KeyError, IndexError, ValueError, TypeError):
        return None, ""


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
    """

    def __init__(self, upstream: str) -> None:
        host, port = upstream.rsplit(":", 1)
        self.upstream = (host, int(port))
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
        exp, subject = _token_expiry(auth)
        now = time.time()
        if exp is None or not subject or exp <= now:
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
