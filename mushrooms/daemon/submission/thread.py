"""The daemon's submitter and the thread that runs it (``[submit]``; the lifecycle is
:mod:`~mushrooms.daemon.submission.submitter`'s).
"""

from __future__ import annotations

import logging
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
    """
    from ..drain import OutboxDrain
    from .remote import make_client

    sub = submit
    if not sub.enabled:
        return None
    client = make_client(sub.target, sub.url, token, sub.timeout_s)
    submitter = Submitter(store, sub, export, client, on_outbox=on_outbox, on_result=on_result)

    def one_pass() -> int:
        if closing is not None and closing():
            return 0
        return submitter.step()

    drain = OutboxDrain(one_pass, sub.retry_initial_s, sub.retry_max_s, name="submit")
    log.info("event=submit_enabled target=%s url=%s dry_run=%s alert_types=%s min_coverage=%g max_exposures=%d",
             sub.target, sub.url, str(sub.dry_run).lower(), ",".join(sub.alert_types), sub.min_coverage,
             sub.max_exposures)
    return submitter, drain
