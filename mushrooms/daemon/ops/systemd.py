"""systemd notification protocol (``sd_notify``) without extra dependencies.

The service tells systemd when it is ready, that it is alive (watchdog),
what it is doing (status) and that it is stopping.  Outside systemd
(``$NOTIFY_SOCKET`` unset) every call is a cheap no-op.
"""

from __future__ import annotations

import logging
import os
import socket
import time
from typing import Collection, Sequence

__all__ = ["Notifier", "Readiness", "watchdog_interval_s"]

log = logging.getLogger("mushrooms.daemon.notify")
#: the service's own log lines (consuming or not)
service_log = logging.getLogger("mushrooms.daemon")


def watchdog_interval_s(environ: dict[str, str] | None = None) -> float | None:
    """Interval (s) at which to ping the watchdog, or None when it is off.

    systemd sets ``$WATCHDOG_USEC`` (and ``$WATCHDOG_PID``) when the unit has
    ``WatchdogSec=``; we ping at half that period, as sd_watchdog_enabled(3)
    recommends.

    Parameters
    ----------
    environ : dict, optional
        Environment to read (default ``os.environ``).
    """
    env = os.environ if environ is None else environ
    usec = env.get("WATCHDOG_USEC")
    if not usec:
        return None
    pid = env.get("WATCHDOG_PID")
    if pid and pid.isdigit() and int(pid) != os.getpid():
        return None
    try:
        value = int(usec)
    except ValueError:
        return None
    return value / 1e6 / 2.0 if value > 0 else None


class Notifier:
    """Send ``sd_notify`` datagrams to ``$NOTIFY_SOCKET``.

    Parameters
    ----------
    address : str, optional
        Socket path; default ``$NOTIFY_SOCKET``.  A leading ``@`` names an
        abstract socket.  None or empty disables notifications.
    """

    def __init__(self, address: str | None = None) -> None:
        addr = os.environ.get("NOTIFY_SOCKET", "") if address is None else address
        self.address: str | bytes | None = None
        if addr:
            self.address = "\0" + addr[1:] if addr.startswith("@") else addr

    @property
    def enabled(self) -> bool:
        """True when running under a service manager that listens."""
        return self.address is not None

    def send(self, *assignments: str) -> bool:
        """Send ``KEY=VALUE`` lines; returns False when nothing was sent."""
        if self.address is None:
            return False
        payload = "\n".join(assignments).encode()
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
                sock.setblocking(False)  # a stuck listener must never stall the service
                sock.connect(self.address)
                sock.send(payload)
        except OSError as exc:
            log.warning("event=sd_notify_failed error=%r", str(exc))
            return False
        return True

    def ready(self, status: str = "") -> bool:
        """READY=1 (and an optional status line)."""
        lines = ["READY=1"] + ([f"STATUS={status}"] if status else [])
        return self.send(*lines)

    def watchdog(self) -> bool:
        """WATCHDOG=1: the main loop is alive."""
        return self.send("WATCHDOG=1")

    def status(self, text: str) -> bool:
        """STATUS=...: one line shown by ``systemctl status``."""
        return self.send(f"STATUS={text}")

    def reloading(self) -> bool:
        """RELOADING=1 while the configuration is reloaded."""
        return self.send("RELOADING=1")

    def stopping(self) -> bool:
        """STOPPING=1: a clean stop has begun."""
        return self.send("STOPPING=1")


class Readiness:
    """READY=1 once the consumer group assigned partitions (or after ``wait_s``), STATUS on every change.

    Tells systemd the truth: a daemon that consumes nothing says so in its
    status line, and is ready only when it consumes (or has waited long
    enough that systemd must not time the start out).

    Parameters
    ----------
    notifier : Notifier
        Where READY and STATUS go.
    wait_s : float
        Longest wait (s) for partitions before READY=1 is sent anyway.
    """

    def __init__(self, notifier: Notifier, wait_s: float) -> None:
        self.notifier = notifier
        self.wait_s = wait_s
        self.sent = False  # READY=1 was sent
        self.consuming = False  # partitions were assigned at the last look
        self.wait_from = 0.0  # time.monotonic() the wait for partitions began

    def start_waiting(self) -> None:
        """The consumer is open: the wait for partitions begins now."""
        self.wait_from = time.monotonic()

    def due(self, assigned: bool) -> bool:
        """Whether :meth:`track` has something to say (a change, or READY not sent yet)."""
        return self.consuming != assigned or not self.sent

    def track(self, partitions: Collection[tuple[str, int]], topics: Sequence[str], since_start_s: float) -> None:
        """Look at the assigned ``(topic, partition)`` pairs; log a change, send READY or STATUS."""
        names = ",".join(topics)
        assigned = bool(partitions)
        if assigned and not self.consuming:
            service_log.info("event=consuming partitions=%s since_start_s=%.2f", " ".join(
                f"{t}[{p}]" for t, p in sorted(partitions)), since_start_s)
        elif self.consuming and not assigned:
            service_log.warning("event=not_consuming reason='partitions revoked; waiting for the group to assign "
                                "them'")
        self.consuming = assigned
        status = (f"consuming {names}" if assigned else
                  f"NOT consuming yet: waiting for the consumer group to assign partitions of {names}")
        if not self.sent:
            if assigned or time.monotonic() - self.wait_from > self.wait_s:
                self.sent = True
                self.notifier.ready(status)
        else:
            self.notifier.status(status)
