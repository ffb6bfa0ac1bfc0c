"""The greedy scheduler (gwemopt-like), the baseline every other method is measured against.

Fields in order of their probability, each observed in the filter sequence
with the cadence between its visits as soon as a window and the telescope
allow (:mod:`.schedule`); it solves no model, so no equation of
``docs/design/milp.md`` is its own: it keeps the rules the checker applies
(F1-F9 of ``docs/design/sequences.md``) and is the first stage and the
start of every MILP portfolio (:mod:`..portfolio`).

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .schedule import greedy_schedule, time_passes

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "greedy_schedule": ".schedule", "time_passes": ".schedule",
}

__all__ = [
    "greedy_schedule", "time_passes",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
