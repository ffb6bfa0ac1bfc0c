"""Alert semantics: what an LVK ``igwn.gwalert`` notice means and what to do about it.

* :mod:`.alert` -- parse JSON / Avro / archived VOEvent notices into an :class:`Alert`.
* :mod:`.policy` -- the ``[policy]`` table and :func:`evaluate` (keep or ignore, and why).
* :mod:`.decisions` -- :func:`decide` per superevent: plan, rerun, duplicate, withdraw, ignore.

Never imports :mod:`mushrooms.daemon`.  The names below are imported on first
use (PEP 562), so reading the ``[policy]`` table (:mod:`.policy`) does not
load the notice parser's astropy through this ``__init__``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..scheduler_core.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, for type checkers and editors
    from .alert import ALERT_TYPES, Alert, EventDetails, ExternalCoinc, NoticeError, parse_notice
    from .decisions import ACTIONS, Decision, EventState, Ledger, MemoryLedger, decide
    from .policy import PolicyConfig, Verdict, evaluate, superevent_kind

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    **dict.fromkeys(("ALERT_TYPES", "Alert", "EventDetails", "ExternalCoinc", "NoticeError", "parse_notice"), ".alert"),
    **dict.fromkeys(("ACTIONS", "Decision", "EventState", "Ledger", "MemoryLedger", "decide"), ".decisions"),
    **dict.fromkeys(("PolicyConfig", "Verdict", "evaluate", "superevent_kind"), ".policy"),
}

__all__ = [
    "ALERT_TYPES", "Alert", "EventDetails", "ExternalCoinc", "NoticeError", "parse_notice",
    "ACTIONS", "Decision", "EventState", "Ledger", "MemoryLedger", "decide",
    "PolicyConfig", "Verdict", "evaluate", "superevent_kind",
]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
