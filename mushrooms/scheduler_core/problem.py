"""The planning problem every scheduler solves, and what a scheduler returns.

A :class:`PlanningProblem` gathers, once per sky map and start time, all that
the greedy and MILP schedulers need: the observable ZTF fields, their
footprints at the working resolution, their observability windows over the
horizon and the sky map's probability.  Building it is the slow part; the
schedulers themselves are pure functions of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np
from astropy.time import Time

from .budget import Clock, new_clock
from .config import PlanningConfig
from .plan.document import Observation
from .sky.footprints import Footprints
from .sky.windows import Windows

__all__ = ["PlanningProblem", "ScheduleResult", "StopCheck", "Scheduler", "UpperBound", "PortfolioEntry",
           "DetectionReport"]

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
    clock : Clock
        The budget the schedulers read (:mod:`.budget`): a work clock when
        ``config.deterministic``, else the wall clock; a fresh one per
        problem unless given (a problem derived with ``dataclasses.replace``
        shares its parent's, :func:`~.planner.optimise` starts a fresh one).
    """

    config: PlanningConfig
    start: Time
    prob: np.ndarray
    field_ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    footprints: Footprints
    windows: Windows
    clock: Clock | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.clock is None:
            object.__setattr__(self, "clock", new_clock(self.config.deterministic))

    @property
    def horizon_s(self) -> float:
        """Horizon length (s)."""
        return self.config.horizon_s

    @property
    def telescope(self) -> str:
        """Name of the telescope planned (``ztf``, ``ls4`` ...): ``config.telescope``'s, a file's stem."""
        from .instruments.active import telescope_name

        return telescope_name(self.config.telescope)

    def centre(self, field_id: int) -> tuple[float, float]:
        """(ra, dec) in deg of a candidate field."""
        k = self.footprints.row(field_id)
        return float(self.ra[k]), float(self.dec[k])


@dataclass(frozen=True)
class UpperBound:
    """A certified coverage upper bound and how it was obtained.

    The published one is :func:`~.schedulers.bounds.certified_bound.certified_upper_bound`:
    the least of the online bound (U4) and, within ``bound_time_limit_s``,
    the interval bound (V1-V4).

    Attributes
    ----------
    value : float
        Upper bound on the probability coverage of any plan.
    status : str
        ``online`` (greedy online bound), ``optimal`` (the relaxation
        solved), ``all_fields`` (every pairable field fits, no solve
        needed), ``dual_bound`` (time limit: the solver's proven bound) or
        ``empty``.
    n_pairable : int
        Fields able to hold a pair.
    max_fields : int
        K, most fields the observable time holds.
    runtime_s : float
        Wall time (s).
    method : str
        Which bound ``value`` is: ``online`` (U4, :func:`~.schedulers.bounds.coverage_bound.coverage_upper_bound`;
        also its ``empty`` and ``all_fields`` cases), ``milp`` (U0 solved) or
        ``interval`` (V1-V4, :func:`~.schedulers.bounds.interval_bound.interval_upper_bound`,
        when it is below U4).
    margin : float
        What ``value`` carries above the computed bound (``milp.md`` B1, B2):
        the rounding margin of an exact bound, or the solver's tolerances of
        a MILP's dual bound.
    """

    value: float
    status: str
    n_pairable: int
    max_fields: int
    runtime_s: float
    method: str = "online"
    margin: float = 1e-9


@dataclass(frozen=True)
class PortfolioEntry:
    """One candidate a portfolio (:func:`~.schedulers.portfolio.portfolio.best_of`) compared.

    Attributes
    ----------
    name : str
        The stage (``greedy``, ``slots``, ``blocks``).
    solver, status : str
        The candidate's own.
    mip_gap : float or None
        The candidate's own.
    coverage : float
        Its coverage as it will be published (after the least-gain rule), the
        portfolio's criterion.
    """

    name: str
    solver: str
    status: str
    mip_gap: float | None
    coverage: float


@dataclass(frozen=True)
class DetectionReport:
    """What the detection stage (:func:`~.schedulers.detection.stage.detection_stage`) did.

    Attributes
    ----------
    choice : str
        ``detection`` (its plan was kept), ``coverage`` or ``coverage (no
        distance layers)`` (the coverage plan was).
    budget_s, runtime_s : float
        The stage's budget and wall time (s), rounded to ms.
    expected_detections_coverage : float or None
        Expected detections of the coverage plan it started from (None
        without distance layers).
    coverage_floor : float or None
        The floor (X6) its plans had to reach.
    grids : tuple of dict
        Free-form per-grid diagnostics (``grid``, ``status``, and for the
        grids solved ``expected_detections``, ``coverage``, ``above_floor``, and
        for a plan the rule would keep ``coverage_as_executed`` and
        ``above_executed_floor`` (X10), ...).
    """

    choice: str
    budget_s: float
    runtime_s: float
    expected_detections_coverage: float | None = None
    coverage_floor: float | None = None
    grids: tuple[Mapping[str, Any], ...] = ()


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
    mip_bound : float or None
        The MILP's proven bound on its objective for the solve kept (slots,
        blocks; None for greedy and a greedy fallback): ``metrics.mip_bound``.
    upper_bound : UpperBound or None
        The certified coverage upper bound (:mod:`.schedulers.bounds.coverage_bound`),
        attached to every MILP scheduler's result (slots, blocks, hybrid);
        None for greedy: ``metrics.upper_bound``.
    dropped_by_slews : tuple of int
        Field IDs the scheduler dropped because the real slews pushed an
        exposure out of its window (slots, blocks).
    dropped_low_gain : tuple of int
        Field IDs the least-gain rule removed (:func:`~.schedulers.gain.drop_low_gain`;
        empty until the rule was applied).
    solver_status : str or None
        The MILP backend's own status when ``status`` is not it (a greedy
        fallback: ``no_incumbent_greedy_fallback``).
    grid : str or None
        The slot grid of the plan kept (slots).
    expected_detections : float or None
        Expected detections (X1) of these exposures as published, when a
        scheduler scored them (the detection stage).
    expected_detections_lightcurve : str or None
        The light curve (``config.detection_lightcurve``) ``expected_detections``
        was scored with (None: another kilonova or not scored).
    portfolio : tuple of PortfolioEntry
        The candidates a portfolio (the hybrid) compared, in its order; empty
        for a single scheduler.
    portfolio_choice : str or None
        The stage whose plan the portfolio kept.
    detection : DetectionReport or None
        What the detection stage did (None when it did not run).
    details : dict
        Free-form diagnostics only (model size, per-grid or per-attempt
        runs, retries, ...); nothing here is read back by the planner.
    """

    observations: tuple[Observation, ...]
    solver: str
    status: str
    mip_gap: float | None = None
    runtime_s: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)
    mip_bound: float | None = None
    upper_bound: UpperBound | None = None
    dropped_by_slews: tuple[int, ...] = ()
    dropped_low_gain: tuple[int, ...] = ()
    solver_status: str | None = None
    grid: str | None = None
    expected_detections: float | None = None
    expected_detections_lightcurve: str | None = None
    portfolio: tuple[PortfolioEntry, ...] = ()
    portfolio_choice: str | None = None
    detection: DetectionReport | None = None


#: A scheduler: ``scheduler(problem, should_stop)`` plans the horizon within
#: ``problem.config.time_limit_s`` (:mod:`.solvers_registry` names them).
Scheduler = Callable[[PlanningProblem, "StopCheck | None"], ScheduleResult]
