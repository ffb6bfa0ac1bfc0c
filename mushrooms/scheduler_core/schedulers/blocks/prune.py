"""Pruning: shortlist the N fields that together cover the most probability.

MUSHROOMS' first step (paper, section 3) is a max weighted coverage over the
observable field grid, solved with the classic greedy algorithm (Nemhauser,
Wolsey & Fisher 1978, a (1 - 1/e) approximation).  Lazy evaluation keeps it
fast: a field's marginal gain only shrinks as others are picked, so a stale
gain is an upper bound and only the top of the heap is ever re-evaluated.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from ...config import PlanningConfig
from ...sky.footprints import Footprints
from ...problem import PlanningProblem
from ...sky.windows import Windows

__all__ = ["greedy_max_coverage", "default_shortlist_size", "shortlist_fields", "observable_time_s", "schedulable_rows",
           "SHORTLIST_MIN", "SHORTLIST_MAX", "SHORTLIST_SLACK"]

#: The shortlist is never smaller than this (small sky maps still get choice)...
SHORTLIST_MIN = 12
#: ...nor larger than this (keeps the block MILP solvable within seconds).
SHORTLIST_MAX = 90
#: Shortlist this many times the fields the horizon can hold, so the MILP
#: can trade probability against visibility.
SHORTLIST_SLACK = 1.5


def greedy_max_coverage(footprints: Footprints, prob: np.ndarray, n: int) -> np.ndarray:
    """Rows of up to ``n`` fields maximising the probability of their union (lazy greedy).

    Parameters
    ----------
    footprints : Footprints
        Candidate fields' pixel lists (CSR).
    prob : numpy.ndarray
        Probability per pixel (NESTED, same nside).
    n : int
        Largest number of fields to pick.

    Returns
    -------
    numpy.ndarray
        Row indices into ``footprints`` in the order picked; fields adding
        no probability are never picked, so fewer than ``n`` may come back.
    """
    indptr, indices = footprints.indptr, footprints.indices
    uncovered = np.asarray(prob, float).copy()
    gains = footprints.field_probability(uncovered)
    # max-heap of (-gain, row); ties broken by row for reproducibility
    heap = [(-g, k) for k, g in enumerate(gains) if g > 0]
    heapq.heapify(heap)
    picked: list[int] = []
    while heap and len(picked) < n:
        neg, k = heapq.heappop(heap)
        pix = indices[indptr[k]:indptr[k + 1]]
        gain = float(uncovered[pix].sum())
        if gain <= 0:
            continue
        if heap and gain < -heap[0][0]:
            heapq.heappush(heap, (-gain, k))  # stale: re-insert with its true gain
            continue
        picked.append(k)
        uncovered[pix] = 0.0
    return np.asarray(picked, dtype=np.int64)


def observable_time_s(windows: Windows, horizon_s: float) -> float:
    """Length (s) of the union of all observability windows inside the horizon.

    Parameters
    ----------
    windows : Windows
        Windows of the candidate fields.
    horizon_s : float
        Horizon length (s).

    Returns
    -------
    float
        Seconds during which at least one candidate field is observable.
    """
    start = np.clip(windows.start, 0.0, horizon_s)
    end = np.clip(windows.end, 0.0, horizon_s)
    keep = end > start
    if not keep.any():
        return 0.0
    order = np.argsort(start[keep])
    s, e = start[keep][order], end[keep][order]
    reach = np.maximum.accumulate(e)
    # a new interval begins where the start exceeds everything reached so far
    new = np.concatenate([[True], s[1:] > reach[:-1]])
    group = np.cumsum(new) - 1
    group_end = np.zeros(group[-1] + 1)
    np.maximum.at(group_end, group, e)
    return float((group_end - s[new]).sum())


def default_shortlist_size(problem: PlanningProblem) -> int:
    """Shortlist size N sized from what the horizon can hold.

    Every planned field costs two visits of ``exposure + slew estimate``;
    the observable time (union of the candidates' windows in the horizon)
    therefore holds about ``T_obs / (2 (t_exp + t_slew))`` fields.  N is
    that capacity times :data:`SHORTLIST_SLACK` (the MILP needs choice: not
    every high-probability field is up at the right time), clipped to
    [:data:`SHORTLIST_MIN`, :data:`SHORTLIST_MAX`] and to the candidates.

    Parameters
    ----------
    problem : PlanningProblem

    Returns
    -------
    int
    """
    cfg: PlanningConfig = problem.config
    if cfg.n_fields is not None:
        return min(cfg.n_fields, len(problem.field_ids))
    t_obs = observable_time_s(problem.windows, cfg.horizon_s)
    capacity = t_obs / (2.0 * (cfg.exposure_s + cfg.slew_estimate_s))
    n = int(math.ceil(SHORTLIST_SLACK * capacity))
    return int(min(max(n, SHORTLIST_MIN), SHORTLIST_MAX, len(problem.field_ids)))


def schedulable_rows(problem: PlanningProblem, min_window_s: float) -> np.ndarray:
    """Rows of fields with at least one window (inside the horizon) of ``min_window_s`` or more.

    A field whose windows are all shorter than the shortest block can never
    be planned; keeping it out of the shortlist leaves room for one that can.
    """
    w = problem.windows
    length = np.clip(w.end, 0.0, problem.horizon_s) - np.clip(w.start, 0.0, problem.horizon_s)
    long_enough = np.unique(w.field_ids[length >= min_window_s])
    return np.flatnonzero(np.isin(problem.field_ids, long_enough))


def shortlist_fields(problem: PlanningProblem, n: int | None = None, min_window_s: float = 0.0) -> np.ndarray:
    """Rows of the problem's candidate fields kept for the block MILP.

    Parameters
    ----------
    problem : PlanningProblem
    n : int, optional
        Shortlist size; default :func:`default_shortlist_size`.
    min_window_s : float
        Only fields with a window at least this long (s) take part.

    Returns
    -------
    numpy.ndarray
        Sorted row indices into ``problem.field_ids``.
    """
    n = default_shortlist_size(problem) if n is None else n
    rows = schedulable_rows(problem, min_window_s)
    fp = problem.footprints
    counts = fp.indptr[rows + 1] - fp.indptr[rows]
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    offsets = np.repeat(fp.indptr[rows] - indptr[:-1], counts)
    sub = Footprints(fp.nside, fp.field_ids[rows], indptr, fp.indices[np.arange(indptr[-1]) + offsets])
    return np.sort(rows[greedy_max_coverage(sub, problem.prob, n)])
