"""One coordinated plan for several telescopes on one sky map (``docs/design/telescopes.md``, section 5, J1-J8).

* :mod:`.cells`: the cells over the union of the telescopes' shortlists, and
  the joint metrics (union, each telescope's share and own share, the
  probability covered by more than one telescope);
* :mod:`.model`: the joint slot model, J1-J4 (each telescope's slot rows
  S1-S2, the cells coupling them, J2);
* :mod:`.ascent`: each telescope alone, and the coordinate ascent of J6
  (its first sweep is gwemopt's iterative tiling);
* :mod:`.bound`: the joint relaxation J7 and the published bound J8;
* :mod:`.schedule`: :func:`joint_schedule`, the plan (J6) with its metrics
  and bound.

The names below are imported on first use (PEP 562).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .bound import JointBound, joint_upper_bound
    from .cells import JointMetrics, joint_metrics
    from .schedule import JointResult, joint_schedule

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "JointBound": ".bound", "joint_upper_bound": ".bound",
    "JointMetrics": ".cells", "joint_metrics": ".cells",
    "JointResult": ".schedule", "joint_schedule": ".schedule",
}

__all__ = ["JointBound", "joint_upper_bound", "JointMetrics", "joint_metrics", "JointResult", "joint_schedule"]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
