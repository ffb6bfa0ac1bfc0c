"""The daemon's log lines: one line per record on stdout, with a syslog priority prefix under journald."""

from __future__ import annotations

import logging
import os
import sys

__all__ = ["JournalFormatter", "setup_logging"]


class JournalFormatter(logging.Formatter):
    """One line per record; ``<N>`` syslog priority prefix under journald."""

    PRIORITY = {logging.DEBUG: 7, logging.INFO: 6, logging.WARNING: 4, logging.ERROR: 3, logging.CRITICAL: 2}

    def __init__(self, journald: bool) -> None:
        fmt = "%(levelname)s %(name)s: %(message)s" if journald else \
            "%(asctime)s %(levelname)s %(name)s: %(message)s"
        super().__init__(fmt)
        self.journald = journald

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record).replace("\n", " | ")
        if self.journald:
            return f"<{self.PRIORITY.get(record.levelno, 6)}>{text}"
        return text


def setup_logging(level: int | None = None) -> None:
    """Structured one-line logs on stdout (journald adds time and unit)."""
    root = logging.getLogger()
    if level is not None:
        root.setLevel(level)
    for h in list(root.handlers):
        root.removeHandler(h)
    handler = logging.StreamHandler(sys.stdout)
    handler.setFormatter(JournalFormatter(journald=bool(os.environ.get("JOURNAL_STREAM"))))
    root.addHandler(handler)
    for noisy in ("apscheduler", "astropy"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
