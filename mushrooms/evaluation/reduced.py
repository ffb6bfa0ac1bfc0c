"""Reduced planning problems: the top ``k`` fields of a sky map, for the exact model.

The exact model (:mod:`.exact`) proves optimality only on a few tens of
fields, so the benchmark asks every scheduler the same smaller question:
the ``k`` pairable fields (:func:`~mushrooms.scheduler_core.schedulers.bounds.coverage_bound.pairable_rows`)
that the greedy maximum-coverage order picks first, with their footprints
and all their windows, the same sky map, night and configuration.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..scheduler_core.problem import PlanningProblem
from ..scheduler_core.schedulers.blocks.schedule import shortlist_footprints
from ..scheduler_core.schedulers.bounds.coverage_bound import pairable_rows
from ..scheduler_core.schedulers.blocks.prune import greedy_max_coverage
from ..scheduler_core.sky.windows import Windows

__all__ = ["top_fields", "restrict_problem", "reduced_problem"]


def top_fields(problem: PlanningProblem, k: int) -> np.ndarray:
    """Rows of the ``k`` pairable fields picked first by greedy maximum coverage.

    Parameters
    ----------
    problem : PlanningProblem
    k : int
        Number of fields (fewer come back when fewer are pairable or hold
        probability).

    Returns
    -------
    numpy.ndarray
        Sorted rows of ``problem.field_ids``.
    """
    rows = pairable_rows(problem)
    picked = greedy_max_coverage(shortlist_footprints(problem.footprints, rows), problem.prob, k)
    return np.sort(rows[picked])


def restrict_problem(problem: PlanningProblem, rows: np.ndarray, **config_changes) -> PlanningProblem:
    """The same problem on some fields only (footprints, centres and windows of those rows).

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray
        Rows of ``problem.field_ids`` kept.
    **config_changes
        Replaced fields of ``problem.config`` (e.g. ``objective="coverage"``).

    Returns
    -------
    PlanningProblem
    """
    rows = np.sort(np.asarray(rows, np.int64))
    ids = problem.field_ids[rows]
    w = problem.windows
    keep = np.isin(w.field_ids, ids)
    config = dataclasses.replace(problem.config, **config_changes) if config_changes else problem.config
    return dataclasses.replace(
        problem, config=config, field_ids=ids, ra=problem.ra[rows], dec=problem.dec[rows],
        footprints=shortlist_footprints(problem.footprints, rows),
        windows=Windows(w.field_ids[keep], w.start[keep], w.end[keep]))


def reduced_problem(problem: PlanningProblem, k: int, **config_changes) -> PlanningProblem:
    """:func:`restrict_problem` to the :func:`top_fields` of ``problem``."""
    return restrict_problem(problem, top_fields(problem, k), **config_changes)
