"""The health listener's HTTP server: idle or dripping connections cost a file descriptor, never a thread.

The standard library's threaded server gives every accepted connection a
thread that blocks reading its request line, so a few idle connections (a
slowloris) hold every thread and ``/healthz`` goes unanswered; each one timing
out then prints a raw traceback (``socketserver``'s ``handle_error``).

Here one thread (:meth:`Front.serve_forever`) accepts connections and reads
their request heads without blocking (``selectors``), each within
``timeout_s`` of its accept (however slowly it drips); only a complete head
goes to one of ``workers`` threads, which runs the WSGI app and writes the
answer (HTTP/1.0, ``Connection: close``; a request body is never read).
At most ``max_open`` connections are kept: a new one closes the oldest still
sending its head, so the newest (the scraper's, which sends its head at once)
is always read.  Nothing is printed: dropped connections are counted and
said in one log line (``event=metrics_connections_dropped``) at most once a
minute.
"""

from __future__ import annotations

import errno
import io
import logging
import queue
import selectors
import socket
import threading
import time
from typing import Any, Callable, Iterable
from urllib.parse import unquote
from wsgiref.handlers import SimpleHandler

__all__ = ["Front", "MAX_OPEN", "HEAD_BYTES", "LOG_EVERY_S"]

log = logging.getLogger("mushrooms.daemon.health")

#: Connections kept open at most (each a file descriptor; the unit's LimitNOFILE is far above).
MAX_OPEN = 512
#: Largest request head read (bytes); a longer one is answered 431.
HEAD_BYTES = 16384
#: Dropped connections are said in one log line at most this often (s).
LOG_EVERY_S = 60.0

_WSGI = Callable[[dict, Callable[..., Any]], Iterable[bytes]]


class _Quiet(SimpleHandler):
    """wsgiref's handler without the process environment in ``environ`` and without printed tracebacks."""

    os_environ: dict = {}
    server_software = "mushrooms"

    def log_exception(self, exc_info: Any) -> None:
        log.error("event=metrics_request_failed error=%r", f"{exc_info[0].__name__}: {exc_info[1]}")


class Front:
    """Accept, read heads in one thread, answer in ``workers`` threads.

    Parameters
    ----------
    host, port : str, int
        Where to listen (port 0: any free port; see :attr:`address`).
    app : callable
        The WSGI application.
    workers : int
        Threads that answer complete requests (the only ones besides :meth:`serve_forever`'s).
    timeout_s : float
        Time (s) a connection has, from its accept, to send its whole request head; also the
        socket timeout of writing the answer.
    max_open : int
        Connections kept open at most; beyond, the oldest still reading its head is closed.
    """

    def __init__(self, host: str, port: int, app: _WSGI, workers: int = 4, timeout_s: float = 10.0,
                 max_open: int = MAX_OPEN) -> None:
        family, _, _, _, where = socket.getaddrinfo(host or None, port, type=socket.SOCK_STREAM,
                                                    flags=socket.AI_PASSIVE)[0]
        self._listen = socket.socket(family, socket.SOCK_STREAM)
        try:
            self._listen.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._listen.bind(where)
            self._listen.listen(128)
        except OSError:
            self._listen.close()
            raise
        self._listen.setblocking(False)
        self.address: tuple[str, int] = self._listen.getsockname()[:2]
        self.app, self.timeout_s, self.max_open = app, float(timeout_s), int(max_open)
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._listen, selectors.EVENT_READ, None)
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._sel.register(self._wake_r, selectors.EVENT_READ, "wake")
        self._heads: dict[socket.socket, tuple[float, bytearray, Any]] = {}  # accept order: deadline, head, peer
        self._jobs: queue.Queue[tuple[socket.socket, bytes, Any] | None] = queue.Queue(max(4, 4 * int(workers)))
        self._stop = threading.Event()
        self._serving, self._served = threading.Event(), threading.Event()
        #: connections dropped since the last log line, by why
        self.dropped = {"timed_out": 0, "evicted": 0, "refused": 0, "failed": 0}
        self._said = -LOG_EVERY_S
        self._workers = [threading.Thread(target=self._work, name=f"metrics-http-{k}", daemon=True)
                         for k in range(max(1, int(workers)))]
        for t in self._workers:
            t.start()

    # ------------------------------------------------------------ the reading thread
    def serve_forever(self, poll_interval: float = 0.5) -> None:
        """Accept and read heads until :meth:`close`."""
        self._serving.set()
        try:
            while not self._stop.is_set():
                for key, _ in self._sel.select(timeout=min(poll_interval, self.timeout_s)):
                    if key.data is None:
                        self._accept()
                    elif key.data == "wake":
                        self._wake_r.recv(64)
                    else:
                        self._read(key.fileobj)
                self._expire(time.monotonic())
                self._say()
        finally:
            self._served.set()

    def _accept(self) -> None:
        for _ in range(256):  # drain the backlog, a bounded batch at a time
            try:
                conn, peer = self._listen.accept()
            except BlockingIOError:
                return
            except OSError as exc:  # out of file descriptors: make room, try again at the next turn
                if exc.errno in (errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM) and self._heads:
                    self._drop(next(iter(self._heads)), "evicted")
                    return
                if exc.errno in (errno.ECONNABORTED, errno.EPROTO):
                    continue
                raise
            if len(self._heads) >= self.max_open:
                self._drop(next(iter(self._heads)), "evicted")  # the oldest one still sending its head
            conn.setblocking(False)
            self._heads[conn] = (time.monotonic() + self.timeout_s, bytearray(), peer)
            self._sel.register(conn, selectors.EVENT_READ, "head")

    def _read(self, conn: Any) -> None:
        entry = self._heads.get(conn)
        if entry is None:
            return
        try:
            piece = conn.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            piece = b""
        if not piece:
            self._forget(conn)
            conn.close()
            return
        head = entry[1]
        head += piece
        end = head.find(b"\r\n\r\n")
        if end < 0 and len(head) > HEAD_BYTES:
            self._forget(conn)
            _answer_now(conn, b"431 Request Header Fields Too Large")
            return
        if end < 0:
            return
        self._forget(conn)
        try:
            self._jobs.put_nowait((conn, bytes(head[:end]), entry[2]))
        except queue.Full:  # every worker busy and a queue behind them: say so at once, never wait
            self.dropped["refused"] += 1
            _answer_now(conn, b"503 Service Unavailable")

    def _forget(self, conn: Any) -> None:
        self._heads.pop(conn, None)
        try:
            self._sel.unregister(conn)
        except (KeyError, ValueError):
            pass

    def _drop(self, conn: Any, why: str) -> None:
        self._forget(conn)
        self.dropped[why] += 1
        conn.close()

    def _expire(self, now: float) -> None:
        while self._heads:
            conn, (deadline, _, _) = next(iter(self._heads.items()))
            if deadline > now:
                return
            self._drop(conn, "timed_out")

    def _say(self) -> None:
        now = time.monotonic()
        if not any(self.dropped.values()) or now - self._said < LOG_EVERY_S:
            return
        self._said = now
        log.warning("event=metrics_connections_dropped %s open=%d (idle or too slow to send a request within "
                    "%.0f s, or beyond %d open; counted, said at most once every %.0f s)",
                    " ".join(f"{k}={v}" for k, v in self.dropped.items()), len(self._heads), self.timeout_s,
                    self.max_open, LOG_EVERY_S)
        self.dropped = dict.fromkeys(self.dropped, 0)

    # ------------------------------------------------------------ the answering threads
    def _work(self) -> None:
        while True:
            job = self._jobs.get()
            if job is None:
                return
            conn, head, peer = job
            try:
                conn.setblocking(True)
                conn.settimeout(self.timeout_s)
                conn.sendall(self._respond(head, peer))
                conn.shutdown(socket.SHUT_WR)
            except OSError:  # the client went away or stopped reading: counted, never printed
                self.dropped["failed"] += 1
            except Exception as exc:  # a fault of ours: one line, never a traceback on stderr
                log.error("event=metrics_request_failed error=%r", f"{type(exc).__name__}: {exc}")
            finally:
                conn.close()

    def _respond(self, head: bytes, peer: Any) -> bytes:
        """The whole answer to one request head (status line, headers, body; no body for HEAD)."""
        environ = _environ(head, peer, self.address)
        if environ is None:
            return b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
        out = io.BytesIO()
        handler = _Quiet(io.BytesIO(b""), out, io.StringIO(), environ, multithread=True, multiprocess=False)
        handler.run(self.app)
        data = out.getvalue()
        if environ["REQUEST_METHOD"] == "HEAD":
            data = data[:data.find(b"\r\n\r\n") + 4]
        return data

    def close(self) -> None:
        """Stop accepting, close every connection, stop the threads."""
        self._stop.set()
        try:
            self._wake_w.send(b"x")
        except OSError:
            pass
        if self._serving.is_set():
            self._served.wait(5.0)
        for _ in self._workers:
            try:
                self._jobs.put(None, timeout=self.timeout_s)
            except queue.Full:  # workers stuck on dead clients: they are daemon threads, left to their timeout
                break
        for t in self._workers:
            t.join(self.timeout_s + 1.0)
        for conn in list(self._heads):
            self._forget(conn)
            conn.close()
        for s in (self._listen, self._wake_r, self._wake_w):
            s.close()
        self._sel.close()


def _answer_now(conn: Any, status: bytes) -> None:
    """A short answer without waiting (best effort), then close."""
    try:
        conn.send(b"HTTP/1.0 " + status + b"\r\nContent-Length: 0\r\nConnection: close\r\n\r\n")
    except OSError:
        pass
    conn.close()


def _environ(head: bytes, peer: Any, address: tuple[str, int]) -> dict[str, Any] | None:
    """The WSGI environ of a request head; None when it is not HTTP."""
    lines = head.decode("latin-1").split("\r\n")
    parts = lines[0].split()
    if len(parts) != 3 or not parts[2].startswith("HTTP/"):
        return None
    method, target, version = parts
    path, _, query = target.partition("?")
    env: dict[str, Any] = {"REQUEST_METHOD": method, "SCRIPT_NAME": "", "PATH_INFO": unquote(path, "latin-1"),
                           "QUERY_STRING": query, "SERVER_PROTOCOL": version, "SERVER_NAME": str(address[0]),
                           "SERVER_PORT": str(address[1]), "REMOTE_ADDR": str(peer[0]) if peer else "",
                           "CONTENT_LENGTH": "0"}
    for line in lines[1:]:
        name, sep, value = line.partition(":")
        if not sep or not name.strip():
            continue
        key = name.strip().upper().replace("-", "_")
        if key in ("CONTENT_TYPE", "CONTENT_LENGTH"):
            env[key] = value.strip() if key == "CONTENT_TYPE" else "0"  # a body is never read
        else:
            env[f"HTTP_{key}"] = value.strip()
    return env
