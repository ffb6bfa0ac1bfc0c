"""The summary files beside a plan document: ``P.txt`` (text) and ``P.html`` (the page, picture embedded).

:func:`write_summaries` is what ``mushrooms plan -o P.json`` calls;
:class:`SummarisingSink` wraps the outbox's directory sink so every published
plan and not_observable answer gets both files beside its JSON: the text at
once (milliseconds), then on a thread of its own the queue names (timing
the queue set takes a second) and the page (the picture a few seconds), and
the text again with the names: publishing never waits for them.  The
summaries of a plan are written again when a later message changes what
they say: a ``plan_final`` verdict (the revision is final) and a
``submission`` document (what became of its queues).
"""

from __future__ import annotations

import json
import logging
import queue
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from .page import summary_html
from .summary import summary_text

__all__ = ["write_summaries", "summary_paths", "SummarisingSink", "SUMMARISED_TYPES", "revision_in_force",
           "submission_words"]

log = logging.getLogger("mushrooms.report")

#: Outbound message types that get a summary.
SUMMARISED_TYPES = ("plan", "not_observable")

#: ``doc -> (queue names, what becomes of them)``: the names a plan is (to be) submitted as.
QueueNamer = Callable[[Mapping[str, Any]], "tuple[Sequence[str], str]"]


def summary_paths(json_path: str | Path) -> tuple[Path, Path]:
    """``P.txt`` and ``P.html`` beside ``P.json``."""
    p = Path(json_path)
    return p.with_suffix(".txt"), p.with_suffix(".html")


def write_summaries(doc: Mapping[str, Any], json_path: str | Path, picture_png: bytes | None = None,
                    text: str | None = None, queues: Sequence[str] | None = None,
                    queue_note: str = "") -> tuple[Path, Path]:
    """Write the text and HTML summaries of ``doc`` beside ``json_path`` (atomically); their paths.

    ``queues``/``queue_note``: the revision's ZTF queue names and what became of them (:func:`.facts.plan_facts`).
    """
    from ..outputs import write_bytes_atomic

    txt, page = summary_paths(json_path)
    text = text if text is not None else summary_text(doc, queues=queues, queue_note=queue_note)
    write_bytes_atomic(txt, text.encode())
    write_bytes_atomic(page, summary_html(doc, picture_png, queues=queues, queue_note=queue_note).encode())
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


#: A ``submission`` document's state in words (``{target}``: kowalski or skyportal; plan-format.md).
SUBMISSION_WORDS = {
    "pending": "submission to {target} pending",
    "submitted": "submitted to {target}",
    "replaced": "submitted to {target}, since replaced by a newer plan's queues",
    "deleted": "submitted to {target}, since deleted (the event was retracted)",
    "rejected": "rejected by {target}",
    "failed": "submission to {target} failed",
    "skipped": "not submitted",
}


def submission_words(state: str, target: str) -> str:
    """What a submission state means for the plan's queues, in words (``submitted to kowalski``)."""
    return SUBMISSION_WORDS.get(str(state), "submission {state}").format(target=target, state=state)


def _picture(doc: Mapping[str, Any], skymap: Any = None) -> bytes | None:
    """The plan's picture (on its sky map when given, else the airmass panel and timeline), or None."""
    if not doc.get("observations"):
        return None
    try:
        from ..plotting import plan_picture_png
        from ..scheduler_core import Plan

        return plan_picture_png(Plan.from_document(dict(doc)), skymap, dpi=90)
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
    queues : callable, optional
        ``doc -> (names, words)``: the ZTF queue names a published plan goes
        (or would go) to and what becomes of them (the daemon's
        :func:`~mushrooms.daemon.submission.names.publish_queues`); None: no
        queue shown until a ``submission`` document names them.
    skymap_for : callable, optional
        ``doc -> SkyMap or None``: the plan's sky map, read on the page
        thread, so the page shows the plan on the sky; None (or a map that
        cannot be read): the airmass panel and timeline only.
    """

    #: Pictures kept for the pages written again (a plan_final, a submission): the picture does not change.
    PICTURES_KEPT = 8

    def __init__(self, sink: Any, max_pending: int = 16, queues: QueueNamer | None = None,
                 skymap_for: Callable[[Mapping[str, Any]], Any] | None = None):
        self.sink = sink
        self.directory = getattr(sink, "directory", None)
        self.queues = queues
        self.skymap_for = skymap_for
        #: ``doc -> lines``: every other telescope's part of the plan's revision (issue 53), after the summary
        self.parts_note: Callable[[Mapping[str, Any]], list[str]] | None = None
        self._pictures: OrderedDict[str, bytes | None] = OrderedDict()
        self._pending: queue.Queue[tuple[dict[str, Any], Path] | None] = queue.Queue(max_pending)
        self._thread = threading.Thread(target=self._draw_pages, name="mushrooms-summary", daemon=True)
        self._thread.start()

    def path_for(self, message: Mapping[str, Any]) -> Path:
        return self.sink.path_for(message)

    def publish(self, message: dict[str, Any]) -> None:
        self.sink.publish(message)  # the JSON first: the summary never delays the plan
        kind = message.get("type")
        try:
            if kind in SUMMARISED_TYPES:
                self._summarise(dict(message), self.sink.path_for(message))
            elif kind in ("plan_final", "submission") and isinstance(message.get("plan_id"), str):
                self._refresh(message["plan_id"])
        except Exception:
            log.exception("event=summary_failed plan_id=%s", message.get("plan_id"))

    def _names(self, doc: Mapping[str, Any]) -> tuple[tuple[str, ...], str]:
        if self.queues is None or doc.get("type") != "plan":
            return (), ""
        try:
            names, words = self.queues(doc)
        except Exception:
            log.exception("event=summary_queue_names_failed plan_id=%s", doc.get("plan_id"))
            return (), ""
        return tuple(names), words

    def _current(self, doc: dict[str, Any], target: Path) -> dict[str, Any]:
        """The document as it stands now: final once its ``plan_final`` verdict is out (its JSON says false)."""
        if doc.get("type") == "plan" and self.sink.path_for({"type": "plan_final", "plan_id": doc.get("plan_id")}
                                                            ).is_file():
            doc = dict(doc, final=True)
        return doc

    def _summarise(self, doc: dict[str, Any], target: Path) -> None:
        """The text at once (the queue names when a submission document gave them), then on the page thread
        the names (:attr:`queues`: they take the queue set's timing) and the page, and the text again."""
        from ..outputs import write_bytes_atomic

        doc = self._current(doc, target)
        names, words = self._submitted(target) or ((), "")
        text = summary_text(doc, queues=names, queue_note=words)
        write_bytes_atomic(summary_paths(target)[0], self._with_parts(doc, text).encode())
        try:
            self._pending.put_nowait((doc, target))
        except queue.Full:
            log.warning("event=summary_page_skipped plan_id=%s reason=queue_full", doc.get("plan_id"))

    def _with_parts(self, doc: Mapping[str, Any], text: str, html: bool = False) -> str:
        """``text`` (the summary or the page) with the other telescopes' parts after it; as it was without."""
        lines = self.parts_note(doc) if self.parts_note is not None else []
        if not lines:
            return text
        if not html:
            return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"
        import html as html_text

        block = "<pre class=\"telescopes\">" + html_text.escape("\n".join(lines)) + "</pre>\n"
        return text.replace("</body>", block + "</body>", 1) if "</body>" in text else text + block

    def _refresh(self, plan_id: str) -> None:
        """Write a published plan's summaries again: final when its ``plan_final`` is out, with the queues and
        the state of its newest ``submission`` document (read back from the directory, so a restart agrees)."""
        target = self.sink.path_for({"type": "plan", "plan_id": plan_id})
        try:
            doc = json.loads(target.read_text())
        except (OSError, ValueError):
            return  # not a plan this directory holds (or not yet)
        if isinstance(doc, dict) and doc.get("type") == "plan":
            self._summarise(doc, target)

    @staticmethod
    def _submitted(target: Path) -> tuple[tuple[str, ...], str] | None:
        """The queue names and state of a plan's newest ``submission`` document beside it, None without one."""
        newest: tuple[str, float, dict[str, Any]] | None = None
        for path in target.parent.glob(f"{target.stem}-submission-*.json"):
            try:
                sub = json.loads(path.read_text())
                key = (str(sub.get("created", "")), path.stat().st_mtime)
            except (OSError, ValueError, AttributeError):
                continue
            if isinstance(sub, dict) and (newest is None or key > newest[:2]):
                newest = (*key, sub)
        if newest is None:
            return None
        sub = newest[2]
        names = sub.get("queue_names") or ([sub["queue_name"]] if sub.get("queue_name") else [])
        return tuple(str(n) for n in names), submission_words(sub.get("state", "?"), sub.get("target", "?"))

    def _page_picture(self, doc: Mapping[str, Any]) -> bytes | None:
        plan_id = str(doc.get("plan_id"))
        if plan_id in self._pictures:
            return self._pictures[plan_id]
        skymap = None
        if self.skymap_for is not None and doc.get("observations"):
            try:
                skymap = self.skymap_for(doc)
            except Exception:
                log.exception("event=summary_skymap_failed plan_id=%s", plan_id)
        picture = _picture(doc, skymap)
        self._pictures[plan_id] = picture
        while len(self._pictures) > self.PICTURES_KEPT:
            self._pictures.popitem(last=False)
        return picture

    def _draw_pages(self) -> None:
        while True:
            item = self._pending.get()
            if item is None:
                return
            doc, target = item
            try:
                from ..outputs import write_bytes_atomic

                # the latest word on the plan (a verdict or a submission may have come since it was queued)
                doc = self._current(doc, target)
                names, words = self._submitted(target) or self._names(doc)
                txt, html_path = summary_paths(target)
                text = summary_text(doc, queues=names, queue_note=words)
                write_bytes_atomic(txt, self._with_parts(doc, text).encode())
                page = summary_html(doc, self._page_picture(doc), queues=names, queue_note=words)
                write_bytes_atomic(html_path, self._with_parts(doc, page, html=True).encode())
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
