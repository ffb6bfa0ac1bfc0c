"""The planning problem every scheduler solves, and what a scheduler returns.

A :class:`PlanningProblem` gathers, once per sky map and start time, all that
the greedy and MILP schedulers need: the observable ZTF fields, their
footprints at the working resolution, their observability windows over the
horizon and the sky map's probability.  Building it is the slow part; the
schedulers themselves are pure functions of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from astropy.time import Time

from .config import PlanningConfig
from .plan.document import Observation
from .sky.footprints import Footprints
from .sky.windows import Windows

__all__ = ["PlanningProblem", "ScheduleResult", "StopCheck"]

#: A callable the scheduler polls; True means "stop now, return what you have".
StopCheck = Callable[[], bool]


@dataclass(frozen=True)
class PlanningProblem:
    """Everything a scheduler needs for one sky map, start time and config.

    Attributes
    ----------
    config : PlanningConfig
        Planning parameters.
    start : astropy.time.Time
        Horizon start (UTC); all times are seconds since it.
    prob : numpy.ndarray
        Sky map probability per pixel (NESTED, ``footprints.nside``).
    field_ids, ra, dec : numpy.ndarray
        Candidate fields (observable at least once in the horizon) and their
        centres (deg), all of the same length.
    footprints : Footprints
        Footprints of the candidate fields, same row order as ``field_ids``.
    windows : Windows
        Observability windows of the candidate fields.
    """

    config: PlanningConfig
    start: Time
    prob: np.ndarray
    field_ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    footprints: Footprints
    windows: Windows

    @property
    def horizon_s(self) -> float:
        """Horizon length (s)."""
        return self.config.horizon_s

    def centre(self, field_id: int) -> tuple[float, float]:
        """(ra, dec) in deg of a candidate field."""
        k = self.footprints.row(field_id)
        return float(self.ra[k]), float(self.dec[k])


@dataclass(frozen=True)
class ScheduleResult:
    """What a scheduler returns, before it becomes a :class:`~.plan.Plan`.

    Attributes
    ----------
    observations : tuple of Observation
        In time order, times in s since the horizon start.
    solver : str
        ``greedy``, ``milp:highs``, ``milp:gurobi``, ...
    status : str
        ``optimal``, ``time_limit``, ``interrupted``, ``greedy``,
        ``no_incumbent_greedy_fallback``, ...
    mip_gap : float or None
        Relative gap at the end (None without a MILP).
    runtime_s : float
        Wall time (s) of this scheduler.
    details : dict
        Free-form diagnostics (model size, bound, retries, ...).
    """

    observations: tuple[Observation, ...]
    solver: str
    status: str
    mip_gap: float | None = None
    runtime_s: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)
