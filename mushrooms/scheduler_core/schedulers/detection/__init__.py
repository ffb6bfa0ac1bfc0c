"""The detection objective on the slot model: plan for the kilonova found, not only the area covered.

Section 4 of ``docs/design/detection.md`` (built on S1-S3 of
``docs/design/milp.md``):

* :mod:`.model`: each (field, slot) pair's reach, the distance levels and
  their weights, the rows X2-X6;
* :mod:`.ceiling`: the most expected detections any plan can have (when the
  stage cannot change the answer);
* :mod:`.stage`: the stage after the coverage portfolio
  (:func:`detection_stage`): solve, keep the plan only when it is preferred
  (``docs/design/detection.md``, section 5).

The names below are imported on first use (PEP 562): importing one module
of the package loads only what that module needs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...lazy import lazy_exports

if TYPE_CHECKING:
    from .stage import detection_stage, plan_expected_detections, coverage_floor
    from .ceiling import detection_ceiling
    from .model import DetectionModel, build_detection_model

#: public name -> the submodule (relative) that defines it
_EXPORTS = {
    "detection_stage": ".stage", "plan_expected_detections": ".stage", "coverage_floor": ".stage",
    "detection_ceiling": ".ceiling",
    "DetectionModel": ".model", "build_detection_model": ".model",
}

__all__ = [
    "detection_stage", "plan_expected_detections", "coverage_floor", "detection_ceiling", "DetectionModel",
    "build_detection_model",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, __all__)
