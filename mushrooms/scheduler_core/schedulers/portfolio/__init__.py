"""Schedulers made of schedulers: the hybrid portfolio and its large-neighbourhood search.

* :mod:`.portfolio`: stages run in turn on one budget, the plan ZTF's
  scheduler executes best kept (Q15 of ``docs/design/executed.md``), the
  bound attached and the early stop at it (V6 of ``docs/design/milp.md``);
  it registers the named schedulers (``greedy``, ``slots``, ``blocks`` /
  ``milp``, ``hybrid``) in :mod:`mushrooms.scheduler_core.solvers_registry`;
* :mod:`.continuous`: the continuous-time model of the full rules, C0-C6
  (section 5 of ``docs/design/milp.md``);
* :mod:`.lns`: the hybrid's ``lns`` stage, time slices of the incumbent
  re-solved exactly with that model, H1-H5 (section 6); one slice's
  fields, model, re-solve and rule check in :mod:`.lns_slice`.

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .portfolio import Stage, Portfolio, best_of, with_upper_bound, slots_from_greedy, blocks, hybrid
    from .lns import lns_improve
    from .continuous import ExactData, ExactModel, exact_data, build_exact_model

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "Stage": ".portfolio", "Portfolio": ".portfolio", "best_of": ".portfolio", "with_upper_bound":
    ".portfolio", "slots_from_greedy": ".portfolio", "blocks": ".portfolio", "hybrid": ".portfolio",
    "lns_improve": ".lns",
    "ExactData": ".continuous", "ExactModel": ".continuous", "exact_data": ".continuous", "build_exact_model":
    ".continuous",
}

__all__ = [
    "Stage", "Portfolio", "best_of", "with_upper_bound", "slots_from_greedy", "blocks", "hybrid",
    "lns_improve", "ExactData", "ExactModel", "exact_data", "build_exact_model",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
