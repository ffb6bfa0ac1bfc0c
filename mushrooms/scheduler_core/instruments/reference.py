"""ZTF's planning thresholds, the reference every telescope's are scaled from (I5).

Standard library only: :mod:`..config` takes its defaults from here and
:func:`.defaults.scaled_thresholds` scales them by a telescope's covering
area, so neither imports the other (``docs/design/telescopes.md`` I5).
"""

from __future__ import annotations

__all__ = ["ZTF_THRESHOLDS"]

#: ``[scheduler] min_gain`` (least probability a field must add) and ``min_coverage`` (least a plan must
#: cover) for ZTF's 47.7 deg² field: the defaults of :class:`~..config.PlanningConfig`.
ZTF_THRESHOLDS: dict[str, float] = {"min_gain": 0.001, "min_coverage": 0.01}
