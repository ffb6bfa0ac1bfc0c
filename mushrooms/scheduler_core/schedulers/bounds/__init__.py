"""Certified upper bounds on the coverage of any rule-abiding plan.

Sections 3 and 4 of ``docs/design/milp.md``:

* :mod:`.coverage_bound`: the relaxation U0-U3 and the greedy online bound
  U4, with the solver margins (B1, B2 of section 4);
* :mod:`.interval_bound`: the relaxation that counts the competition for
  time, V1-V4;
* :mod:`.certified_bound`: the published bound, the least of U4 and V (V5),
  every MILP plan's ``metrics.upper_bound``;
* :mod:`.outer_windows`: window ends refined below the visibility grid step
  (V7).

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .certified_bound import certified_upper_bound
    from .coverage_bound import coverage_upper_bound, UpperBound
    from .interval_bound import interval_upper_bound
    from .outer_windows import refined_windows, refined_problem

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "certified_upper_bound": ".certified_bound",
    "coverage_upper_bound": ".coverage_bound", "UpperBound": ".coverage_bound",
    "interval_upper_bound": ".interval_bound",
    "refined_windows": ".outer_windows", "refined_problem": ".outer_windows",
}

__all__ = [
    "certified_upper_bound", "coverage_upper_bound", "UpperBound", "interval_upper_bound", "refined_windows",
    "refined_problem",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
