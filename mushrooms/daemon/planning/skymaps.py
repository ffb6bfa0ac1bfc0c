"""The sky map a stored plan was made on, read back from its notice: the outbox page draws the plan on it.

The state keeps every notice that needed planning with its bytes
(``notices.raw``); a plan's job names its notice.  The map is the one whose
SHA-256 the plan document carries (a joint map, or the GW map it fell back
to), at the plan's HEALPix resolution.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any, Callable, Mapping

from ...handlers.alert import parse_notice
from ...handlers.localization import skymap_for_sha
from ...scheduler_core.sky.sniff import is_fits

if TYPE_CHECKING:
    from ..state.store import Store

__all__ = ["plan_skymap_reader"]

log = logging.getLogger("mushrooms.daemon")


def plan_skymap_reader(store: Store, max_bytes: int) -> Callable[[Mapping[str, Any]], Any]:
    """``doc -> SkyMap or None``: the sky map of a plan the store holds (None: not found, not readable).

    Parameters
    ----------
    store : Store
        The daemon's state (its ``plans``, ``jobs`` and ``notices``).
    max_bytes : int
        ``[policy] max_skymap_bytes``: the largest map decoded.
    """
    def read(doc: Mapping[str, Any]) -> Any:
        from ...scheduler_core import read_skymap

        row = store.connection().execute(
            "SELECT j.notice_id, j.skymap_sha256 FROM plans p JOIN jobs j ON j.job_id = p.job_id"
            " WHERE p.plan_id = ?", (str(doc.get("plan_id")),)).fetchone()
        raw = store.notice_raw(int(row[0])) if row is not None else None
        if raw is None:
            return None
        if is_fits(raw):
            data = raw
        else:
            alert = parse_notice(raw)
            sha = (doc.get("event") or {}).get("skymap_sha256") or row[1]
            found = skymap_for_sha(alert, sha) or skymap_for_sha(alert, row[1])
            if found is None:
                return None
            data = found[1]
        nside = int((doc.get("config") or {}).get("nside") or 64)
        return read_skymap(data, nside=nside, max_bytes=max_bytes)
    return read
