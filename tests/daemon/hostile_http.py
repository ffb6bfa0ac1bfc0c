"""A scripted HTTP server on loopback that answers the way a broken or hostile neighbour does.

Each connection's request (request line, headers, body by ``Content-Length``)
is read and logged, then :attr:`HostileServer.behaviour` writes whatever raw
bytes it likes to the socket: a redirect, an answer dripped one byte at a
time, an answer cut in the middle, text that is not HTTP, an endless body.
:attr:`HostileServer.sent` counts the bytes each behaviour managed to write
before the client went away.
"""

from __future__ import annotations

import socket
import threading
import time
from typing import Callable

Behaviour = Callable[[socket.socket, dict], None]


class HostileServer:
    """``with HostileServer(behaviour) as s: ... s.url``; :attr:`requests` holds what came in."""

    def __init__(self, behaviour: Behaviour) -> None:
        self.behaviour = behaviour
        self.requests: list[dict] = []
        self.sent: list[int] = []
        self._sock = socket.create_server(("127.0.0.1", 0))
        self._sock.settimeout(0.2)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self._sock.getsockname()[1]}"

    def __enter__(self) -> "HostileServer":
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5)
        self._sock.close()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._sock.accept()
            except OSError:
                continue
            threading.Thread(target=self._one, args=(conn,), daemon=True).start()

    def _one(self, conn: socket.socket) -> None:
        conn.settimeout(5)
        data = b""
        try:
            while b"\r\n\r\n" not in data:
                chunk = conn.recv(65536)
                if not chunk:
                    return
                data += chunk
            head, body = data.split(b"\r\n\r\n", 1)
            lines = head.decode("latin-1").split("\r\n")
            method, path, _ = lines[0].split(" ", 2)
            headers = {k.strip().lower(): v.strip() for k, v in (line.split(":", 1) for line in lines[1:])}
            n = int(headers.get("content-length", 0))
            while len(body) < n:
                body += conn.recv(65536)
            request = {"method": method, "path": path, "headers": headers, "body": body}
            self.requests.append(request)
            counter = _Counted(conn)
            try:
                self.behaviour(counter, request)
            except OSError:
                pass
            self.sent.append(counter.n)
        except OSError:
            pass
        finally:
            try:
                conn.close()
            except OSError:
                pass


class _Counted:
    """A socket that counts what was sent through it."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock, self.n = sock, 0

    def sendall(self, data: bytes) -> None:
        self.sock.sendall(data)
        self.n += len(data)

    def shutdown(self, how: int) -> None:
        self.sock.shutdown(how)


def answer(status: str, body: bytes = b"", headers: dict[str, str] | None = None) -> Behaviour:
    """A complete answer (``status`` like ``"302 Found"``)."""
    def send(sock, request) -> None:
        hdrs = {"Content-Length": str(len(body)), "Connection": "close", **(headers or {})}
        sock.sendall(f"HTTP/1.1 {status}\r\n".encode() + b"".join(f"{k}: {v}\r\n".encode() for k, v in hdrs.items())
                     + b"\r\n" + body)
    return send


def drip(data: bytes, every_s: float) -> Behaviour:
    """``data`` one byte every ``every_s`` seconds (a server that holds the client without ever timing out a recv)."""
    def send(sock, request) -> None:
        for i in range(len(data)):
            sock.sendall(data[i:i + 1])
            time.sleep(every_s)
    return send


def endless(status: str = "200 OK", chunk: bytes = b"x" * 65536, limit: int = 256 * 2**20) -> Behaviour:
    """A ``Content-Length: limit`` answer whose body is written until the client stops reading."""
    def send(sock, request) -> None:
        sock.sendall(f"HTTP/1.1 {status}\r\nContent-Type: application/json\r\nContent-Length: {limit}\r\n\r\n"
                     .encode())
        for _ in range(limit // len(chunk)):
            sock.sendall(chunk)
    return send


def raw(data: bytes) -> Behaviour:
    """``data`` and then the connection closed (a cut answer, or something that is not HTTP)."""
    def send(sock, request) -> None:
        sock.sendall(data)
    return send
