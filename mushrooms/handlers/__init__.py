"""Alert semantics: what an LVK ``igwn.gwalert`` notice means and what to do about it.

* :mod:`.alert` -- parse JSON / Avro / archived VOEvent notices into an :class:`Alert`.
* :mod:`.policy` -- the ``[policy]`` table and :func:`evaluate` (keep or ignore, and why).
* :mod:`.decisions` -- :func:`decide` per superevent: plan, rerun, duplicate, withdraw, ignore.

Never imports :mod:`mushrooms.daemon`.
"""

from .alert import ALERT_TYPES, Alert, EventDetails, ExternalCoinc, NoticeError, parse_notice
from .decisions import ACTIONS, Decision, EventState, Ledger, MemoryLedger, decide
from .policy import PolicyConfig, Verdict, evaluate, superevent_kind

__all__ = [
    "ALERT_TYPES", "Alert", "EventDetails", "ExternalCoinc", "NoticeError", "parse_notice",
    "ACTIONS", "Decision", "EventState", "Ledger", "MemoryLedger", "decide",
    "PolicyConfig", "Verdict", "evaluate", "superevent_kind",
]
