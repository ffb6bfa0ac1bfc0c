"""The published certified coverage bound: the least of the online bound (U4) and the interval bound (V).

Both are relaxations of every rule-abiding plan (``docs/design/milp.md``,
sections "Certified upper bound", U0-U4, and "Interval bound", V1-V4), so
their minimum is one too.  U4 takes a fraction of a second; V solves a
small MILP by separation within ``config.bound_time_limit_s`` (a time limit
only loosens it).  ``bound_time_limit_s = 0`` publishes U4 alone.

The dependency is one way: this module uses :mod:`.interval_bound`, which
uses :mod:`.coverage_bound`; neither of those imports this one, and the schedulers
(:mod:`..portfolio.portfolio`) import only this one.
"""

from __future__ import annotations

from ...problem import PlanningProblem, UpperBound
from .coverage_bound import coverage_upper_bound
from .interval_bound import interval_upper_bound

__all__ = ["certified_upper_bound"]


def certified_upper_bound(problem: PlanningProblem, time_limit_s: float | None = None) -> UpperBound:
    """``min(U4, V)``: the certified bound on the coverage of any plan of ``problem``, as plans publish it.

    Parameters
    ----------
    problem : PlanningProblem
    time_limit_s : float, optional
        Budget (s) of the interval bound; None takes
        ``problem.config.bound_time_limit_s``.  0: U4 only.

    Returns
    -------
    UpperBound
        ``method`` says which bound it is: ``interval`` when V is below U4,
        else ``online`` (U4's result, unchanged but for the wall time).

    Examples
    --------
    No plan of the night can cover more than the bound; the greedy plan is below it:

    >>> from importlib.resources import files
    >>> from astropy.time import Time
    >>> from mushrooms.scheduler_core import PlanningConfig, read_skymap
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> config = PlanningConfig(solver="greedy", nside=64)
    >>> skymap = read_skymap(path, nside=config.nside)
    >>> night = Time("2019-05-01T03:00:00", scale="utc")
    >>> from mushrooms.scheduler_core import make_plan, prepare_problem
    >>> problem = prepare_problem(skymap, config, night)
    >>> bound = certified_upper_bound(problem, time_limit_s=0)  # U4 alone
    >>> bound.method, 0 < bound.value <= 1
    ('online', True)
    >>> make_plan(skymap, config, start=night).metrics.coverage <= bound.value
    True
    """
    # (V5) min(U4, V): interval_upper_bound never returns more than U4, and U4 alone with no budget
    limit = problem.config.bound_time_limit_s if time_limit_s is None else float(time_limit_s)
    if limit <= 0:
        return coverage_upper_bound(problem)
    return interval_upper_bound(problem, time_limit_s=limit)
