"""Progress of a long command on a terminal: one line per stage, the running one with its seconds.

On a terminal (standard error is a TTY) each stage is printed as it starts
and, while it runs, its line shows the seconds spent (and the budget when
there is one), redrawn once a second; when it ends the line is finished
with its time.  When standard error is not a terminal (a pipe, a file, the
journal) nothing is printed: the log lines say the same.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import IO, Any

__all__ = ["Progress"]


class Progress:
    """Stage lines on a terminal; silent otherwise.

    Parameters
    ----------
    name : str
        The command (``plan``), the lines' prefix.
    stream : file, optional
        Default standard error.
    enabled : bool, optional
        Default: the stream is a TTY.
    """

    def __init__(self, name: str, stream: IO[str] | None = None, enabled: bool | None = None):
        self.name = name
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = bool(self.stream.isatty()) if enabled is None else enabled
        self._stage: str | None = None
        self._budget: float | None = None
        self._t0 = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def stage(self, what: str, budget_s: float | None = None) -> None:
        """End the running stage (if any) and start ``what`` (``budget_s``: its time limit, shown)."""
        self.done()
        if not self.enabled:
            return
        self._stage, self._budget, self._t0 = what, budget_s, time.perf_counter()
        self._draw()
        self._stop.clear()
        self._thread = threading.Thread(target=self._tick, daemon=True, name="mushrooms-progress")
        self._thread.start()

    def done(self) -> None:
        """Finish the running stage's line with its time."""
        if self._stage is None:
            return
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._draw(final=True)
        self._stage = None

    def _line(self, final: bool) -> str:
        took = time.perf_counter() - self._t0
        budget = f" of at most {self._budget:.0f} s" if self._budget and not final else ""
        return f"{self.name}: {self._stage} ... {took:.1f} s{budget}" + (" done" if final else "")

    def _draw(self, final: bool = False) -> None:
        self.stream.write("\r\033[K" + self._line(final) + ("\n" if final else ""))
        self.stream.flush()

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            self._draw()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.done()
