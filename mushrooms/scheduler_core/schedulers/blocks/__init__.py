"""The paper's method: prune, the block-division MILP, a shortest path inside each block, real times.

``solver = "blocks"`` (old name ``milp``) reproduces the paper, section 1 of
``docs/design/milp.md``:

* :mod:`.prune`: the shortlist of the fields that together cover the most
  probability (the fields ``j`` every model here and in :mod:`..slots`,
  :mod:`..bounds` is built on);
* :mod:`.model`: the block-division MILP, equations B0-B11 (B1-B7 the
  appendix's constraints, B8-B11 its fixes and valid cuts);
* :mod:`.ordering`: the fields of a block in a shortest open path over
  real slew times;
* :mod:`.schedule`: the scheduler (:func:`milp_schedule`): candidates,
  model, solve, decode, the blocks timed with true overheads.

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .schedule import milp_schedule, shortlist_footprints, time_blocks
    from .model import BlockModel, BlockParams, build_block_model, decode_blocks
    from .prune import shortlist_fields, greedy_max_coverage
    from .ordering import order_fields

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "milp_schedule": ".schedule", "shortlist_footprints": ".schedule", "time_blocks": ".schedule",
    "BlockModel": ".model", "BlockParams": ".model", "build_block_model": ".model", "decode_blocks": ".model",
    "shortlist_fields": ".prune", "greedy_max_coverage": ".prune",
    "order_fields": ".ordering",
}

__all__ = [
    "milp_schedule", "shortlist_footprints", "time_blocks", "BlockModel", "BlockParams", "build_block_model",
    "decode_blocks", "shortlist_fields", "greedy_max_coverage", "order_fields",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
