"""The fixed-grid slot-assignment MILP: every field's visits at fixed times on a grid of slots.

Section 2 of ``docs/design/milp.md``:

* :mod:`.grid`: the time grid, blocks of ``n`` positions with ``k`` filter
  passes each (G1-G3);
* :mod:`.model`: eligibility of (field, slot) pairs and the model, S0-S3
  (one field per position, each field at most once, cell coverage);
* :mod:`.schedule`: the scheduler (:func:`slot_schedule`): a portfolio of
  grids (positions x phases), warm-started, decoded and timed;
* :mod:`.exposure_menu`: the grid with one exposure per field chosen from
  ``exposure_menu_s`` (``docs/design/detection.md``, section 6).

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .schedule import slot_schedule, slot_portfolio, time_slot_plan
    from .grid import SlotGrid, make_slot_grid
    from .model import SlotInstance, SlotModel, slot_instance, build_slot_model, decode_slots

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "slot_schedule": ".schedule", "slot_portfolio": ".schedule", "time_slot_plan": ".schedule",
    "SlotGrid": ".grid", "make_slot_grid": ".grid",
    "SlotInstance": ".model", "SlotModel": ".model", "slot_instance": ".model", "build_slot_model": ".model",
    "decode_slots": ".model",
}

__all__ = [
    "slot_schedule", "slot_portfolio", "time_slot_plan", "SlotGrid", "make_slot_grid", "SlotInstance",
    "SlotModel", "slot_instance", "build_slot_model", "decode_slots",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
