"""Alert semantics: what an LVK ``igwn.gwalert`` notice means and what to do about it.

* :mod:`.alert` -- parse JSON / Avro / archived VOEvent notices into an :class:`Alert`.
* :mod:`.policy` -- the ``[policy]`` table and :func:`evaluate` (keep or ignore, and why).
* :mod:`.decisions` -- :func:`decide` per superevent: plan, rerun, duplicate, withdraw, ignore.

Never imports :mod:`mushrooms.daemon`.  The names below are imported on first
use (PEP 562), so reading the ``[policy]`` table (:mod:`.policy`) does not
load the notice parser's astropy through this ``__init__``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

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


def __getattr__(name: str) -> Any:
    """Import a public name's submodule on first use, then keep the name here."""
    where = _EXPORTS.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(where, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
