"""The thread that sends the other telescopes' SkyPortal parts (``[submit_parts]``), and its token.

An :class:`~mushrooms.daemon.drain.OutboxDrain` named ``submit_parts`` runs
:meth:`~.parts_sender.PartSender.step`, backing off ``retry_initial_s``
doubling to ``retry_max_s`` while requests wait; the service kicks it when a
plan or a withdrawal is stored (a retracted event's parts count as withdrawn
at once), and once at start (what a crash left half done).
"""

from __future__ import annotations

import logging
from typing import Any, Callable

__all__ = ["parts_token", "open_part_sender"]

log = logging.getLogger("mushrooms.daemon.submit_parts")


def parts_token(config: Any) -> str | None:
    """The SkyPortal token when ``[submit_parts]`` sends for real (read before any state is touched).

    Raises
    ------
    CredentialsError
        Enabled, not a dry run, and neither ``skyportal_token`` nor ``$MUSHROOMS_SKYPORTAL_TOKEN`` is set.
    """
    settings = getattr(config, "submit_parts", None)
    if settings is None or not settings.enabled or settings.dry_run:
        return None
    from ..credentials import load_parts_token

    token, source = load_parts_token()
    log.info("event=credentials_found what=skyportal_token source=%s", source)
    return token


def open_part_sender(config: Any, store: Any, token: str | None, closing: Callable[[], bool] | None = None,
                     on_result: Callable[[str, str], None] | None = None,
                     clock: Callable[[], Any] | None = None) -> tuple[Any, Any] | None:
    """(sender, drain) of ``[submit_parts]``; None when it is off (``clock``: the passes' time, for tests)."""
    settings = getattr(config, "submit_parts", None)
    if settings is None or not settings.enabled:
        return None
    from ..drain import OutboxDrain
    from .parts_sender import PartSender
    from .remote import SkyPortalPlans

    sender = PartSender(store, settings, SkyPortalPlans(settings.url, token, settings.timeout_s), on_result, clock)

    def one_pass() -> int:
        return 0 if closing is not None and closing() else sender.step()

    drain = OutboxDrain(one_pass, settings.retry_initial_s, settings.retry_max_s, name="submit_parts")
    log.info("event=submit_parts_enabled url=%s telescopes=%s dry_run=%s", settings.url,
             ",".join(sorted(settings.allocations)) or "-", str(settings.dry_run).lower())
    return sender, drain
