"""One POST to the webhook, over within a hard deadline, never redirected.

:func:`post_once` speaks just enough HTTP/1.1 for a webhook: it connects,
shakes hands (TLS for ``https``, the system's CAs and the host name checked),
sends the request with ``Connection: close``, reads the status line and
closes the socket; the body of the answer is never read.

The deadline is the whole exchange's, not one read's: before each blocking
step (connect, TLS handshake, each send, each read) the socket's timeout is
set to what is left of it, and once it is spent the socket is closed.  A
server that trickles its answer one byte at a time therefore holds the
sender for ``timeout_s`` at most (a per-read timeout, as ``urllib``'s, would
hold it forever).  Name resolution is left to the system resolver and its
own timeouts (``resolv.conf``), which ``timeout_s`` does not bound.

A 3xx answer is returned as it is, never followed: the caller counts it as a
failure (following it would send the message where the webhook's owner did
not mean it to go).
"""

from __future__ import annotations

import socket
import ssl
import time

from .webhook_url import WebhookAddress

__all__ = ["post_once", "PostFailed", "MAX_HEAD_BYTES"]

#: The longest answer head read (status line, interim answers): a webhook's is a few hundred bytes.
MAX_HEAD_BYTES = 64 * 1024


class PostFailed(Exception):
    """The POST did not get a status; ``reason`` is one word for the log (never the URL)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _left(sock: socket.socket | None, deadline: float) -> float:
    """Set ``sock``'s timeout to what is left before ``deadline``; :class:`PostFailed` once spent."""
    left = deadline - time.monotonic()
    if left <= 0:
        raise PostFailed("deadline")
    if sock is not None:
        sock.settimeout(left)
    return left


def _connect(address: WebhookAddress, deadline: float) -> socket.socket:
    try:
        infos = socket.getaddrinfo(address.host, address.port, type=socket.SOCK_STREAM)
    except socket.gaierror:
        raise PostFailed("name_not_resolved") from None
    last = "unreachable"
    for family, kind, proto, _, where in infos:
        sock = socket.socket(family, kind, proto)
        try:
            sock.settimeout(_left(None, deadline))
            sock.connect(where)
            return sock
        except PostFailed:
            sock.close()
            raise
        except ConnectionRefusedError:
            last = "refused"
        except socket.timeout:
            last = "deadline"
        except OSError:
            last = "unreachable"
        sock.close()
    raise PostFailed(last)


def _request(address: WebhookAddress, body: bytes) -> bytes:
    head = (f"POST {address.target} HTTP/1.1\r\nHost: {address.host_header}\r\n"
            f"Content-Type: application/json\r\nUser-Agent: mushrooms-notify\r\n"
            f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n")
    return head.encode("ascii") + body


def _status(sock: socket.socket, deadline: float) -> int:
    """The status of the final answer (interim 1xx answers skipped); the socket's bytes read until it shows."""
    buf = b""
    while True:
        line_end = buf.find(b"\r\n")
        if line_end >= 0:
            parts = buf[:line_end].split(b" ", 2)
            if len(parts) < 2 or not parts[0].startswith(b"HTTP/1.") or not (parts[1].isdigit() and len(parts[1]) == 3):
                raise PostFailed("not_http")
            status = int(parts[1])
            if not 100 <= status < 200:
                return status
            head_end = buf.find(b"\r\n\r\n")
            if head_end >= 0:
                buf = buf[head_end + 4:]
                continue
        if len(buf) > MAX_HEAD_BYTES:
            raise PostFailed("answer_too_long")
        _left(sock, deadline)
        chunk = sock.recv(4096)
        if not chunk:
            raise PostFailed("closed_without_answer")
        buf += chunk


def post_once(address: WebhookAddress, body: bytes, timeout_s: float,
              context: ssl.SSLContext | None = None) -> int:
    """POST ``body`` (JSON) to ``address`` within ``timeout_s`` (s) in all; the answer's HTTP status.

    Parameters
    ----------
    address : WebhookAddress
    body : bytes
    timeout_s : float
        The whole exchange's deadline (s): connect, handshake, send, answer.
    context : ssl.SSLContext, optional
        For ``https`` (default: :func:`ssl.create_default_context`).

    Raises
    ------
    PostFailed
        No status within the deadline, or the connection failed (``reason``).
    """
    deadline = time.monotonic() + float(timeout_s)
    sock = _connect(address, deadline)
    try:
        if address.scheme == "https":
            context = context or ssl.create_default_context()
            sock = context.wrap_socket(sock, server_hostname=address.host, do_handshake_on_connect=False)
            _left(sock, deadline)
            sock.do_handshake()
        view = memoryview(_request(address, body))
        while view:
            _left(sock, deadline)
            view = view[sock.send(view):]
        return _status(sock, deadline)
    except socket.timeout:
        raise PostFailed("deadline") from None
    except ssl.SSLCertVerificationError:
        raise PostFailed("tls_certificate") from None
    except ssl.SSLError:
        raise PostFailed("tls") from None
    except ConnectionError:
        raise PostFailed("connection_reset") from None
    except OSError:
        raise PostFailed("network") from None
    finally:
        sock.close()
