"""The signals ``mushrooms run`` answers; the handlers only set flags, the main loop acts between polls.

SIGTERM/SIGINT stop (a second SIGINT interrupts at once), SIGHUP reloads the
configuration, SIGUSR1 picks up ``mushrooms trigger`` files.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

__all__ = ["Signals", "HANDLED"]

HANDLED = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGUSR1)


class Signals:
    """Three flags the signal handlers set: ``stop``, ``reload`` and ``triggers`` (:class:`threading.Event`)."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        self.reload = threading.Event()
        self.triggers = threading.Event()

    def install(self) -> None:
        """Route :data:`HANDLED` to :meth:`on_signal` (main thread only)."""
        for sig in HANDLED:
            signal.signal(sig, self.on_signal)

    def on_signal(self, signum: int, frame: Any) -> None:
        """Set the signal's flag; a SIGINT while already stopping raises :class:`KeyboardInterrupt`."""
        if signum in (signal.SIGTERM, signal.SIGINT):
            if self.stop.is_set() and signum == signal.SIGINT:
                raise KeyboardInterrupt
            self.stop.set()
        elif signum == signal.SIGHUP:
            self.reload.set()
        elif signum == signal.SIGUSR1:
            self.triggers.set()
