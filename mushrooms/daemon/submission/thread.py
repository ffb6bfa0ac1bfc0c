"""The daemon's submitter and the thread that runs it (``[submit]``; the lifecycle is
:mod:`~mushrooms.daemon.submission.submitter`'s).
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, Any, Callable

from .submitter import Submitter

if TYPE_CHECKING:
    from ...scheduler_core.plan.exports import ExportConfig
    from ..state.store import Store
    from .settings import SubmitConfig

__all__ = ["open_submitter"]

log = logging.getLogger("mushrooms.daemon.submit")


def open_submitter(submit: SubmitConfig, export: ExportConfig, store: Store, token: str | None,
                   on_outbox: Callable[[], None] | None = None, on_result: Callable[[str, str], None] | None = None,
                   closing: Callable[[], bool] | None = None) -> tuple[Submitter, Any] | None:
    """The daemon's submitter and the thread that runs it (a :class:`~mushrooms.daemon.drain.OutboxDrain`, ``submit``).

    Returns None when ``[submit] target = "none"``.  ``kick()`` the drain
    after a plan is stored or a withdrawal recorded; it retries with the
    ``[submit]`` back-off while submissions wait (5xx, timeouts).
    ``closing()`` True makes passes do nothing (the store is being closed).
    While a queue sent without an answer is watched for (``Submitter.watching``:
    not a failure, no back-off), the drain is kicked again after
    ``retry_initial_s``, doubling to ``retry_max_s`` (:class:`_Recheck`).
    """
    from ..drain import OutboxDrain
    from .remote import make_client

    sub = submit
    if not sub.enabled:
        return None
    client = make_client(sub.target, sub.url, token, sub.timeout_s)
    submitter = Submitter(store, sub, export, client, on_outbox=on_outbox, on_result=on_result)
    recheck: list[_Recheck] = []

    def one_pass() -> int:
        if closing is not None and closing():
            return 0
        left = submitter.step()
        if recheck:
            recheck[0].after_pass(submitter.watching)
        return left

    drain = OutboxDrain(one_pass, sub.retry_initial_s, sub.retry_max_s, name="submit")
    recheck.append(_Recheck(drain.kick, sub.retry_initial_s, sub.retry_max_s))
    log.info("event=submit_enabled target=%s url=%s dry_run=%s alert_types=%s min_coverage=%g max_exposures=%d",
             sub.target, sub.url, str(sub.dry_run).lower(), ",".join(sub.alert_types), sub.min_coverage,
             sub.max_exposures)
    return submitter, drain


class _Recheck:
    """Kicks the submitter's drain again while a queue that may still land is watched for.

    One timer at a time; its delay starts at ``initial_s`` and doubles to
    ``max_s`` while the watch goes on, and starts over once nothing is watched.
    """

    def __init__(self, kick: Callable[[], None], initial_s: float, max_s: float) -> None:
        self._kick = kick
        self._initial_s, self._max_s = float(initial_s), float(max_s)
        self._delay_s = self._initial_s
        self._timer: threading.Timer | None = None
        self._lock = threading.Lock()

    def after_pass(self, watching: int) -> None:
        """Called after every pass with the number of rows watching."""
        with self._lock:
            if not watching:
                self._delay_s = self._initial_s
                return
            if self._timer is not None and self._timer.is_alive():
                return
            self._timer = threading.Timer(self._delay_s, self._kick)
            self._timer.daemon = True
            self._timer.name = "submit-recheck"
            self._timer.start()
            self._delay_s = min(self._delay_s * 2.0, self._max_s)
