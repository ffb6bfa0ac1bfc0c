"""The summary files beside a plan document: ``P.txt`` (text) and ``P.html`` (the page, picture embedded).

:func:`write_summaries` is what ``mushrooms plan -o P.json`` calls;
:class:`SummarisingSink` wraps the outbox's directory sink so every published
plan and not_observable answer gets both files beside its JSON: the text at
once (milliseconds), the page on a thread of its own (the picture takes a
second or two), so publishing never waits for matplotlib.
"""

from __future__ import annotations

import logging
import queue
import threading
from pathlib import Path
from typing import Any, Iterable, Mapping

from .page import summary_html
from .summary import summary_text

__all__ = ["write_summaries", "summary_paths", "SummarisingSink", "SUMMARISED_TYPES", "revision_in_force"]

log = logging.getLogger("mushrooms.report")

#: Outbound message types that get a summary.
SUMMARISED_TYPES = ("plan", "not_observable")


def summary_paths(json_path: str | Path) -> tuple[Path, Path]:
    """``P.txt`` and ``P.html`` beside ``P.json``."""
    p = Path(json_path)
    return p.with_suffix(".txt"), p.with_suffix(".html")


def write_summaries(doc: Mapping[str, Any], json_path: str | Path, picture_png: bytes | None = None,
                    text: str | None = None) -> tuple[Path, Path]:
    """Write the text and HTML summaries of ``doc`` beside ``json_path`` (atomically); their paths."""
    from ..outputs import write_bytes_atomic

    txt, page = summary_paths(json_path)
    write_bytes_atomic(txt, (text if text is not None else summary_text(doc)).encode())
    write_bytes_atomic(page, summary_html(doc, picture_png).encode())
    return txt, page


def revision_in_force(documents: Iterable[Mapping[str, Any]]) -> dict[str, Any] | None:
    """Of an event's published documents, the plan in force: its highest revision, marked final when a
    ``plan_final`` verdict names it (the verdict makes the revision final; its document still says
    ``final: false``).  None without a plan."""
    docs = list(documents)
    plans = [d for d in docs if d.get("type") == "plan"]
    if not plans:
        return None
    doc = dict(max(plans, key=lambda d: d.get("revision") or 1))
    if any(d.get("type") == "plan_final" and d.get("plan_id") == doc.get("plan_id") for d in docs):
        doc["final"] = True
    return doc


def _picture(doc: Mapping[str, Any]) -> bytes | None:
    """The plan's airmass picture (no sky map in the outbox), or None when it cannot be drawn."""
    if not doc.get("observations"):
        return None
    try:
        from ..plotting import plan_picture_png
        from ..scheduler_core import Plan

        return plan_picture_png(Plan.from_document(doc), None, dpi=90)
    except Exception:
        log.exception("event=summary_picture_failed plan_id=%s", doc.get("plan_id"))
        return None


class SummarisingSink:
    """A directory sink that also writes each plan's ``.txt`` and ``.html`` summary beside its JSON.

    Parameters
    ----------
    sink : DirectorySink
        The sink that publishes (its ``path_for`` names the JSON file).
    max_pending : int
        Pages waiting to be drawn at most; beyond, the oldest waits are
        dropped (the text summary is always written).
    """

    def __init__(self, sink: Any, max_pending: int = 16):
        self.sink = sink
        self.directory = getattr(sink, "directory", None)
        self._pending: queue.Queue[tuple[dict[str, Any], Path] | None] = queue.Queue(max_pending)
        self._thread = threading.Thread(target=self._draw_pages, name="mushrooms-summary", daemon=True)
        self._thread.start()

    def path_for(self, message: Mapping[str, Any]) -> Path:
        return self.sink.path_for(message)

    def publish(self, message: dict[str, Any]) -> None:
        self.sink.publish(message)  # the JSON first: the summary never delays the plan
        if message.get("type") not in SUMMARISED_TYPES:
            return
        target = self.sink.path_for(message)
        try:
            from ..outputs import write_bytes_atomic

            write_bytes_atomic(summary_paths(target)[0], summary_text(message).encode())
            self._pending.put_nowait((dict(message), target))
        except queue.Full:
            log.warning("event=summary_page_skipped plan_id=%s reason=queue_full", message.get("plan_id"))
        except Exception:
            log.exception("event=summary_failed plan_id=%s", message.get("plan_id"))

    def _draw_pages(self) -> None:
        while True:
            item = self._pending.get()
            if item is None:
                return
            doc, target = item
            try:
                from ..outputs import write_bytes_atomic

                write_bytes_atomic(summary_paths(target)[1], summary_html(doc, _picture(doc)).encode())
            except Exception:
                log.exception("event=summary_page_failed plan_id=%s", doc.get("plan_id"))

    def close(self, timeout_s: float = 30.0) -> None:
        """Draw the pages still waiting (at most ``timeout_s``), then close the sink."""
        try:
            self._pending.put(None, timeout=timeout_s)
        except queue.Full:
            pass
        self._thread.join(timeout_s)
        close = getattr(self.sink, "close", None)
        if close is not None:
            close()

    def __repr__(self) -> str:
        return f"SummarisingSink({self.sink!r})"
