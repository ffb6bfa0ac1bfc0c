"""Greedy baseline scheduler (gwemopt-like), two filters with a cadence.

The night is walked forward in batches.  A batch is filled, one field at a
time, with the observable field that adds the most not-yet-covered
probability, until the batch's first-filter pass lasts long enough that
revisiting its fields in the second filter, in the same order after one
filter change, respects the cadence.  A field is only taken when it is
observable now and (by estimate) when its second visit falls due; when the
real times of a batch put an exposure outside a window, that field is
dropped and the batch re-timed.  When nothing is observable, the clock
jumps to the next window opening.
"""

from __future__ import annotations

import time

import numpy as np

from ..config import PlanningConfig
from ..plan.document import Observation
from ..problem import PlanningProblem, ScheduleResult, StopCheck
from .slew import overhead_time

__all__ = ["greedy_schedule", "time_two_passes"]


def _window_rows(problem: PlanningProblem) -> np.ndarray:
    order = np.argsort(problem.field_ids)
    pos = np.searchsorted(problem.field_ids, problem.windows.field_ids, sorter=order)
    pos = np.clip(pos, 0, len(order) - 1)
    rows = order[pos]
    return np.where(problem.field_ids[rows] == problem.windows.field_ids, rows, -1)


def _observable(rows_of_windows: np.ndarray, w_start: np.ndarray, w_end: np.ndarray,
                t0: np.ndarray, exposure_s: float, n: int) -> np.ndarray:
    """(n,) True where ``[t0[row], t0[row] + exposure]`` lies in a window of that row."""
    valid = rows_of_windows >= 0
    r = rows_of_windows[valid]
    t = t0[r]
    inside = (w_start[valid] <= t) & (t + exposure_s <= w_end[valid])
    out = np.zeros(n, dtype=bool)
    out[r[inside]] = True
    return out


def time_two_passes(
    problem: PlanningProblem,
    rows: list[int],
    free_at: float,
    previous: tuple[float, float, str] | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Start times (s) of a block: ``rows`` in filter 1, then the same in filter 2.

    Each exposure starts as soon as the overheads allow; a second-filter
    exposure also waits until the cadence since its first-filter exposure
    has passed.

    Parameters
    ----------
    problem : PlanningProblem
        Fields, config and slew model.
    rows : list of int
        Candidate rows in observing order.
    free_at : float
        When the telescope is free (s).
    previous : tuple or None
        (ra, dec, filter) of the exposure before the block.

    Returns
    -------
    first, second : numpy.ndarray
        Start times (s) of each row's exposure in each filter.
    """
    cfg = problem.config
    f1, f2 = cfg.filters
    exp = cfg.exposure_s
    ra = problem.ra[rows]
    dec = problem.dec[rows]
    first = np.empty(len(rows))
    second = np.empty(len(rows))
    t = free_at
    prev = previous
    for i in range(len(rows)):
        oh = 0.0 if prev is None else float(overhead_time(
            prev[0], prev[1], ra[i], dec[i], cfg.slew,
            cfg.filter_change_s if prev[2] != f1 else 0.0))
        first[i] = t + oh
        t = first[i] + exp
        prev = (ra[i], dec[i], f1)
    for i in range(len(rows)):
        oh = float(overhead_time(prev[0], prev[1], ra[i], dec[i], cfg.slew,
                                 cfg.filter_change_s if prev[2] != f2 else 0.0))
        second[i] = max(t + oh, first[i] + cfg.cadence_s)
        t = second[i] + exp
        prev = (ra[i], dec[i], f2)
    return first, second


def greedy_schedule(problem: PlanningProblem, should_stop: StopCheck | None = None) -> ScheduleResult:
    """Plan the horizon greedily by marginal probability.

    Parameters
    ----------
    problem : PlanningProblem
        Candidate fields, footprints, windows, config.
    should_stop : callable, optional
        Polled between picks; True stops with the batches made so far.

    Returns
    -------
    ScheduleResult
        Status ``greedy`` (or ``interrupted``).
    """
    t_wall = time.perf_counter()
    cfg: PlanningConfig = problem.config
    f1, f2 = cfg.filters
    exp = cfg.exposure_s
    horizon = cfg.horizon_s
    n = len(problem.field_ids)
    fp = problem.footprints
    w_rows = _window_rows(problem)
    w_start, w_end = problem.windows.start, problem.windows.end
    empty_row = fp.indptr[1:] == fp.indptr[:-1]

    uncovered = problem.prob.copy()
    used = np.zeros(n, dtype=bool)
    observations: list[Observation] = []
    pass_target = max(cfg.cadence_s - cfg.filter_change_s, exp)
    second_delay = max(cfg.cadence_s, pass_target + cfg.filter_change_s) + exp + 60.0
    free_at = 0.0
    previous: tuple[float, float, str] | None = None
    block = 0
    status = "greedy"

    def gains() -> np.ndarray:
        if fp.indices.size == 0:
            return np.zeros(n)
        g = np.add.reduceat(uncovered[fp.indices], fp.indptr[:-1])
        g[empty_row] = 0.0
        return g

    while free_at + exp <= horizon and n:
        if should_stop is not None and should_stop():
            status = "interrupted"
            break
        batch: list[int] = []
        t = free_at
        prev = previous
        saved = uncovered.copy()
        g = gains()
        while True:
            if prev is None:
                oh = np.zeros(n)
            else:
                oh = overhead_time(prev[0], prev[1], problem.ra, problem.dec, cfg.slew,
                                   cfg.filter_change_s if prev[2] != f1 else 0.0)
            ts = t + oh
            cand = ~used & (g > 0) & (ts + exp <= horizon)
            cand &= _observable(w_rows, w_start, w_end, ts, exp, n)
            cand &= _observable(w_rows, w_start, w_end, ts + second_delay, exp, n)
            if not cand.any():
                break
            k = int(np.argmax(np.where(cand, g, -1.0)))
            batch.append(k)
            used[k] = True
            uncovered[fp.indices[fp.indptr[k]:fp.indptr[k + 1]]] = 0.0
            g = gains()
            t = ts[k] + exp
            prev = (problem.ra[k], problem.dec[k], f1)
            if t - free_at >= pass_target:
                break

        if not batch:
            # nothing fits now: jump to the next window opening of a useful field
            useful = ~used & (g > 0)
            useful_windows = (w_rows >= 0) & useful[np.clip(w_rows, 0, max(n - 1, 0))]
            later = w_start[useful_windows & (w_start > free_at)]
            if later.size == 0:
                break
            free_at = max(float(later.min()), free_at + cfg.time_step_s / 2)
            continue

        # time both passes; drop fields whose real times leave their windows
        while batch:
            first, second = time_two_passes(problem, batch, free_at, previous)
            rows = np.asarray(batch)
            ok1 = _observable_each(w_rows, w_start, w_end, rows, first, exp)
            ok2 = _observable_each(w_rows, w_start, w_end, rows, second, exp)
            ok = ok1 & ok2 & (second + exp <= horizon)
            if ok.all():
                break
            bad = [b for b, good in zip(batch, ok) if not good]
            batch = [b for b, good in zip(batch, ok) if good]
            used[bad] = False  # they may still fit a later batch
            uncovered = saved.copy()
            for k in batch:
                uncovered[fp.indices[fp.indptr[k]:fp.indptr[k + 1]]] = 0.0
        if not batch:
            free_at += cfg.time_step_s
            continue

        for k, t1, t2 in zip(batch, first, second):
            fid = int(problem.field_ids[k])
            ra, dec = float(problem.ra[k]), float(problem.dec[k])
            observations.append(Observation(fid, ra, dec, f1, float(t1), exp, block))
            observations.append(Observation(fid, ra, dec, f2, float(t2), exp, block))
        last = batch[-1]
        free_at = float(second[-1] + exp)
        previous = (float(problem.ra[last]), float(problem.dec[last]), f2)
        block += 1

    observations.sort(key=lambda o: o.start)
    return ScheduleResult(
        observations=tuple(observations),
        solver="greedy",
        status=status,
        mip_gap=None,
        runtime_s=time.perf_counter() - t_wall,
        details={"n_blocks": block},
    )


def _observable_each(w_rows: np.ndarray, w_start: np.ndarray, w_end: np.ndarray,
                     rows: np.ndarray, starts: np.ndarray, exposure_s: float) -> np.ndarray:
    """For each (row, start) pair: is ``[start, start + exposure]`` inside a window of that row?"""
    match = w_rows[None, :] == rows[:, None]
    inside = (w_start[None, :] <= starts[:, None]) & (starts[:, None] + exposure_s <= w_end[None, :])
    return np.any(match & inside, axis=1)
