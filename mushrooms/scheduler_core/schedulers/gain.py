"""The least-gain rule: no field is planned for less probability than ``min_gain``.

With no field penalty a scheduler fills the night, however little a field
adds.  This rule is shared by every scheduler, in two places:

* :func:`worth_a_visit` (used by :func:`~.prepare.prepare_problem`): a field
  whose whole footprint holds less than ``min_gain`` can never add that much,
  so it is not even a candidate;
* :func:`drop_low_gain` (used by :func:`~.planner.build_plan` on every
  scheduler's result, so by ``make_plan`` and the bench alike): a field's *added probability* is the probability in its
  footprint that no field observed before it (order of first visit) covers;
  fields adding less than ``min_gain`` to the fields kept before them are
  removed with both their visits (one pass in that order, so every field
  left adds at least ``min_gain``).

Removing whole fields keeps every rule the checker applies (each remaining
field keeps both filters, the cadence apart, inside its windows).
"""

from __future__ import annotations

import dataclasses
from typing import Collection, Sequence

import numpy as np

from ..plan.document import Observation
from ..sky.footprints import Footprints
from ..problem import PlanningProblem, ScheduleResult

__all__ = ["worth_a_visit", "added_probability", "drop_low_gain", "published_coverage"]


def worth_a_visit(footprints: Footprints, prob: np.ndarray, min_gain: float) -> np.ndarray:
    """Mask of fields whose footprint alone holds at least ``min_gain`` (and some probability).

    Parameters
    ----------
    footprints : Footprints
        Fields' pixel lists.
    prob : numpy.ndarray
        Probability per pixel (NESTED, same nside).
    min_gain : float
        Least probability a planned field must add.

    Returns
    -------
    numpy.ndarray
        (n,) bool, in the row order of ``footprints``.
    """
    p = footprints.field_probability(prob)
    return (p > 0) & (p >= min_gain)


def added_probability(field_order: Sequence[int], footprints: Footprints, prob: np.ndarray) -> np.ndarray:
    """Probability each field adds to the fields before it.

    Parameters
    ----------
    field_order : sequence of int
        Field IDs in order of first visit.
    footprints : Footprints
        Holding at least these fields.
    prob : numpy.ndarray
        Probability per pixel.

    Returns
    -------
    numpy.ndarray
        (len(field_order),) added probability (0-1).
    """
    covered = np.zeros(prob.shape, dtype=bool)
    gains = np.zeros(len(field_order))
    for i, fid in enumerate(field_order):  # a loop over fields (tens), not pixels
        pix = footprints.pixels(int(fid))
        new = pix[~covered[pix]]
        gains[i] = float(prob[new].sum())
        covered[pix] = True
    return gains


def drop_low_gain(result: ScheduleResult, footprints: Footprints, prob: np.ndarray,
                  min_gain: float, keep: Collection[int] = ()) -> ScheduleResult:
    """The result without the fields that add less than ``min_gain``.

    Parameters
    ----------
    result : ScheduleResult
        A scheduler's output.
    footprints : Footprints
        The candidates' footprints.
    prob : numpy.ndarray
        Probability per pixel.
    min_gain : float
        Least added probability (0 keeps everything).
    keep : collection of int
        Fields never dropped (F3: a re-plan's later visits of covered
        fields, which add nothing to coverage by definition).

    Returns
    -------
    ScheduleResult
        Same solver and status; ``dropped_low_gain`` lists the removed field
        IDs (empty when none was).
    """
    observations: tuple[Observation, ...] = tuple(result.observations)
    dropped: list[int] = []
    if min_gain > 0 and observations:
        # one pass in order of first visit: a field is judged against the fields kept before it
        covered = np.zeros(prob.shape, dtype=bool)
        for fid in dict.fromkeys(o.field_id for o in observations):
            if fid in keep:
                continue
            pix = footprints.pixels(int(fid))
            if float(prob[pix[~covered[pix]]].sum()) < min_gain:
                dropped.append(int(fid))
            else:
                covered[pix] = True
        gone = set(dropped)
        observations = tuple(o for o in observations if o.field_id not in gone)
    return dataclasses.replace(result, observations=observations, dropped_low_gain=tuple(dropped))


def published_coverage(problem: PlanningProblem, result: ScheduleResult) -> float:
    """Coverage (0-1) of a result as its plan will have it: after :func:`drop_low_gain`."""
    kept = drop_low_gain(result, problem.footprints, problem.prob, problem.config.min_gain)
    return problem.footprints.coverage({o.field_id for o in kept.observations}, problem.prob)
