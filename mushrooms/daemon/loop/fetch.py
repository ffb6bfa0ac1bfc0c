"""Reading the configured source of executed exposures (``[loop] executed_source``): files and HTTP.

The readers (:mod:`mushrooms.handlers.executed`) take content; this module
gets it:

* ``file:PATH``: the JSON-lines file (a missing file is nothing yet);
* ``depot:DIR``: ``DIR/<YYYYMMDD>/ztf_recentproc_<YYYYMMDD>.json`` for every
  night of the span (:func:`~mushrooms.handlers.executed.depot_paths` of the
  span with its end a day later: SkyPortal's ``floor(JD)`` names a night by
  the date of the noon before it, IPAC's files by the night's UT date, so
  both are read; a night without a file is nothing yet);
* ``depot:URL``: the same files over HTTP(S) with basic auth (the token is
  ``USER:PASSWORD``, as IPAC's depot asks); 404 is a night without a file;
* ``skyportal:URL``: ``GET URL/api/observation?telescopeName=Palomar 1.2m
  Oschin&instrumentName=ZTF&startDate=...&endDate=...&numPerPage=1000&pageNumber=n``
  (``skyportal/handlers/api/observation.py``, ``ObservationHandler.get``)
  with ``Authorization: token <token>``, page after page until
  ``totalMatches`` are read.

HTTP is the standard library's ``urllib`` as in :mod:`~mushrooms.daemon.submission.remote`; the token
goes only into the header and is blanked out of any text we log.
"""

from __future__ import annotations

import base64
import json
import logging
import socket
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlencode

from ...handlers.executed_source import ExecutedSource
from ...handlers.secret_text import redact
from ..submission.remote import Unreachable

if TYPE_CHECKING:
    from astropy.time import Time

    from ...scheduler_core.executed import ExecutedExposure

__all__ = ["ExecutedReader", "FetchError", "SKYPORTAL_OBSERVATION_PATH", "SKYPORTAL_TELESCOPE",
           "SKYPORTAL_INSTRUMENT", "PAGE_SIZE"]

log = logging.getLogger("mushrooms.daemon.loop")

SKYPORTAL_OBSERVATION_PATH = "/api/observation"
#: SkyPortal's names of ZTF's telescope and camera (fritz.science; the handler needs both to filter).
SKYPORTAL_TELESCOPE = "Palomar 1.2m Oschin"
SKYPORTAL_INSTRUMENT = "ZTF"
#: Observations per SkyPortal page: its MAX_OBSERVATIONS.
PAGE_SIZE = 1000
#: Most pages read in one poll (100 000 exposures: ZTF takes under a thousand a night).
MAX_PAGES = 100
#: Largest answer or file read (bytes) when the caller gives none: a night's depot file is a few MB.
MAX_BODY_BYTES = 256 * 1024 * 1024
#: Messages of bad records remembered across polls (each is logged once; L16).
_REMEMBERED = 10_000


class _Once(logging.Filter):
    """(L16) Let each distinct message through once: a bad record read again at the next poll is not logged again."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        key = record.getMessage()
        if key in self.seen:
            return False
        if len(self.seen) < _REMEMBERED:
            self.seen.add(key)
        return True


class FetchError(RuntimeError):
    """The source answered, but not with what was asked (an HTTP error status, a refused token)."""


class ExecutedReader:
    """Reads one configured source over a span of time.

    Parameters
    ----------
    source : ExecutedSource
        The parsed ``[loop] executed_source`` (not ``none``).
    token : str or None
        For a URL source: SkyPortal's token, or the depot's ``USER:PASSWORD``.
    timeout_s : float
        One HTTP request (s).
    max_bytes : int
        Largest file or answer read (``[loop] max_source_bytes``); a larger
        one fails the poll with one line.
    max_read_s : float
        Wall-clock budget (s) of one poll's reading (``[loop] max_read_s``):
        a SkyPortal still paginating past it fails the poll with one line.
    program_ids : tuple of int
        A depot's exposures of these programmes only (L18; empty: all).
    """

    def __init__(self, source: ExecutedSource, token: str | None = None, timeout_s: float = 10.0,
                 max_bytes: int = MAX_BODY_BYTES, max_read_s: float = 120.0,
                 program_ids: tuple[int, ...] = ()) -> None:
        if source.kind == "none" or not source.location:
            raise ValueError("no executed source to read")
        self.source = source
        self._token = token
        self.timeout_s = float(timeout_s)
        self.max_bytes = int(max_bytes)
        self.max_read_s = float(max_read_s)
        self.program_ids = tuple(program_ids)
        self._once = _Once()

    def __repr__(self) -> str:  # never the token
        return f"ExecutedReader({self.describe()!r}, token=***)"

    def describe(self) -> str:
        """``kind:location`` for log lines and the table's ``source`` column."""
        return f"{self.source.kind}:{self.source.location}"

    @property
    def is_url(self) -> bool:
        """The source is read over HTTP(S)."""
        return str(self.source.location).startswith(("http://", "https://"))

    def read(self, start: "Time", end: "Time") -> tuple["ExecutedExposure", ...]:
        """What the source holds of the span ``[start, end]`` (a file: all of it), duplicates collapsed (E2).

        Raises
        ------
        InputError
            The content is not the source's shape at all (one line).
        Unreachable
            No HTTP answer (refused, reset, timeout).
        FetchError
            An HTTP error status.
        """
        quiet = logging.getLogger("mushrooms.handlers.executed")
        quiet.addFilter(self._once)
        try:
            return self._read(start, end)
        finally:
            quiet.removeFilter(self._once)

    def _read(self, start: "Time", end: "Time") -> tuple["ExecutedExposure", ...]:
        from ...handlers import executed as readers
        from ...scheduler_core.errors import InputError
        from ...scheduler_core.executed import unique_exposures

        kind, where = self.source.kind, str(self.source.location)
        if kind == "file":
            path = Path(where)
            if not path.exists() and not path.is_symlink():
                log.info("event=executed_not_yet source=%s reason='no such file yet'", self.describe())
                return ()
            from ...inputs import open_regular_file

            # streamed line by line: a large file of bad records costs a line of memory, not the file
            with open_regular_file(path, self.max_bytes, "executed file") as fh:
                return readers.read_jsonl(fh, what=f"executed file {path.name}")
        if kind == "depot":
            found: list[Any] = []
            from astropy.time import TimeDelta

            for rel in readers.depot_paths(start, end + TimeDelta(1.0, format="jd")):
                if self.is_url:
                    data = self._get(f"{where.rstrip('/')}/{rel}", missing_ok=True)
                    if data is not None:
                        found += readers.read_depot(data, what=f"depot file {rel}", program_ids=self.program_ids)
                    continue
                path = Path(where) / rel
                if not path.exists() and not path.is_symlink():
                    continue  # a night without a file: nothing yet
                try:
                    found += readers.read_depot(self._file(path, "depot file"), what=f"depot file {rel}",
                                                program_ids=self.program_ids)
                except InputError as exc:  # (L16) a FIFO, a device, a link loop: one line, once
                    self._warn_once(f"event=executed_file_skipped source={self.describe()} error={str(exc)!r}")
            return unique_exposures(found)
        if kind == "skyportal":
            return unique_exposures(self._skyportal(start, end))
        raise ValueError(f"unknown executed source kind {kind!r}")

    def _file(self, path: Path, what: str) -> bytes:
        """(L16) A regular file's bytes, at most ``max_bytes`` (never a FIFO or device: nothing blocks)."""
        from ...inputs import read_regular_file

        return read_regular_file(path, self.max_bytes, what)

    def _warn_once(self, line: str) -> None:
        if line not in self._once.seen:
            self._once.seen.add(line)
            log.warning("%s", line)

    # ------------------------------------------------------------ SkyPortal
    def _skyportal(self, start: "Time", end: "Time") -> list[Any]:
        from ...handlers.executed import read_skyportal

        base = str(self.source.location).rstrip("/") + SKYPORTAL_OBSERVATION_PATH
        window = {"telescopeName": SKYPORTAL_TELESCOPE, "instrumentName": SKYPORTAL_INSTRUMENT,
                  "startDate": start.utc.isot, "endDate": end.utc.isot, "numPerPage": PAGE_SIZE}
        out: list[Any] = []
        seen = 0
        began = time.monotonic()
        for page in range(1, MAX_PAGES + 2):
            if page > MAX_PAGES or time.monotonic() - began > self.max_read_s:  # (L16) a SkyPortal paging forever
                raise FetchError(f"SkyPortal still paginating after {page - 1} pages and "
                                 f"{time.monotonic() - began:.0f} s ({seen} observations; at most {MAX_PAGES} "
                                 f"pages and [loop] max_read_s = {self.max_read_s:g} s a poll)")
            data = self._get(f"{base}?{urlencode(window | {'pageNumber': page})}")
            assert data is not None
            out += read_skyportal(data, what=f"SkyPortal answer (page {page})")
            observations, total = _page_size(data)
            seen += observations
            if observations == 0 or total is None or seen >= total:
                break
        return out

    # ------------------------------------------------------------ HTTP
    def _headers(self) -> dict[str, str]:
        headers = {"Accept": "application/json"}
        if self._token:
            if self.source.kind == "skyportal":
                headers["Authorization"] = f"token {self._token}"
            else:
                headers["Authorization"] = "Basic " + base64.b64encode(self._token.encode()).decode()
        return headers

    def _get(self, url: str, missing_ok: bool = False) -> bytes | None:
        """The body of ``GET url``; None for a 404 when ``missing_ok``."""
        request = urllib.request.Request(url, method="GET", headers=self._headers())
        try:
            with urllib.request.urlopen(request, timeout=self.timeout_s) as resp:
                body = resp.read(self.max_bytes + 1)
        except urllib.error.HTTPError as exc:
            if exc.code == 404 and missing_ok:
                return None
            try:
                text = exc.read(2000).decode("utf-8", "replace")
            except (OSError, socket.timeout):
                text = ""
            raise FetchError(f"GET {url} answered {exc.code}: {redact(_message(text), self._token)[:300]}") from None
        except (urllib.error.URLError, OSError, socket.timeout) as exc:
            reason = getattr(exc, "reason", exc)
            raise Unreachable(f"GET {url}: {redact(str(reason), self._token)}") from None
        if len(body) > self.max_bytes:
            raise FetchError(f"GET {url}: answer larger than {self.max_bytes} bytes ([loop] max_source_bytes)")
        return body


def _message(text: str) -> str:
    """A server's ``{"message": ...}`` when it gave one, else its text."""
    try:
        doc = json.loads(text)
    except ValueError:
        return text.strip()
    if isinstance(doc, dict) and isinstance(doc.get("message"), str):
        return doc["message"]
    return text.strip()


def _page_size(data: bytes) -> tuple[int, int | None]:
    """Observations on a SkyPortal page and its ``totalMatches`` (None when absent)."""
    try:
        doc = json.loads(data)
    except ValueError:
        return 0, None
    block = doc.get("data", doc) if isinstance(doc, dict) else {}
    observations = block.get("observations") if isinstance(block, dict) else None
    total = block.get("totalMatches") if isinstance(block, dict) else None
    return (len(observations) if isinstance(observations, list) else 0,
            int(total) if isinstance(total, int) and not isinstance(total, bool) else None)
