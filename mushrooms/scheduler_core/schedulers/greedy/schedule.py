"""Greedy baseline scheduler (gwemopt-like): a filter sequence with a cadence.

The night is walked forward in batches.  A batch is filled, one field at a
time, with the observable field that adds the most not-yet-covered
probability, until the batch's first-filter pass lasts long enough that
revisiting its fields in the sequence's next filter, in the same order
after one filter change, respects the cadence.  The batch's fields are then
observed once per filter of the sequence (``config.filters``: two passes
for the pair g, r; three for g, r, g), each pass a cadence after the one
before for every field.  A field is only taken when it is observable now
and (by estimate) when its later visits fall due; when the real times of a
batch put an exposure outside a window, or (a sequence other than a pair,
F6) spread a field's visits over more than the pair separation, that field
is dropped and the batch re-timed.  When nothing is observable, the clock jumps to the next window
opening.
"""

from __future__ import annotations

import time

import numpy as np

from ...config import PlanningConfig
from ...plan.document import Observation
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from ...telescope.slew import overhead_time

__all__ = ["greedy_schedule", "time_passes"]


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


def time_passes(
    problem: PlanningProblem,
    rows: list[int],
    free_at: float,
    previous: tuple[float, float, str] | None,
) -> np.ndarray:
    """Start times (s) of a block: ``rows`` in each filter of the sequence, pass after pass.

    Each exposure starts as soon as the overheads allow; an exposure of a
    later pass also waits until the cadence since the same field's exposure
    in the pass before has passed.

    Parameters
    ----------
    problem : PlanningProblem
        Fields, config (``filters``: one pass each) and slew model.
    rows : list of int
        Candidate rows in observing order.
    free_at : float
        When the telescope is free (s).
    previous : tuple or None
        (ra, dec, filter) of the exposure before the block.

    Returns
    -------
    numpy.ndarray
        (k, len(rows)) start times (s): row ``p`` is the pass in ``filters[p]``.
    """
    cfg = problem.config
    exp = cfg.exposure_s
    ra = problem.ra[rows]
    dec = problem.dec[rows]
    starts = np.empty((len(cfg.filters), len(rows)))
    t = free_at
    prev = previous
    for p, band in enumerate(cfg.filters):
        for i in range(len(rows)):
            if prev is None:
                starts[p, i] = t
            else:
                oh = float(overhead_time(prev[0], prev[1], ra[i], dec[i], cfg.slew,
                                         cfg.filter_change_s if prev[2] != band else 0.0))
                starts[p, i] = t + oh if p == 0 else max(t + oh, starts[p - 1, i] + cfg.cadence_s)
            t = starts[p, i] + exp
            prev = (ra[i], dec[i], band)
    return starts


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

    Examples
    --------
    >>> from importlib.resources import files
    >>> from astropy.time import Time
    >>> from mushrooms.scheduler_core import PlanningConfig, read_skymap
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> config = PlanningConfig(solver="greedy", nside=64)
    >>> skymap = read_skymap(path, nside=config.nside)
    >>> night = Time("2019-05-01T03:00:00", scale="utc")
    >>> from mushrooms.scheduler_core import prepare_problem
    >>> result = greedy_schedule(prepare_problem(skymap, config, night))
    >>> result.status, result.solver
    ('greedy', 'greedy')
    >>> starts = [o.start for o in result.observations]  # s since the horizon start
    >>> starts == sorted(starts) and 0 <= starts[0]
    True

    A stop asked for at once leaves an empty schedule:

    >>> greedy_schedule(prepare_problem(skymap, config, night), should_stop=lambda: True).status
    'interrupted'
    """
    t_wall = time.perf_counter()
    cfg: PlanningConfig = problem.config
    state = _Greedy(problem)
    status = "greedy"
    while state.free_at + cfg.exposure_s <= cfg.horizon_s and state.n:
        if should_stop is not None and should_stop():
            status = "interrupted"
            break
        if not state.affords(1):  # (S4) the next field's visits would pass the open-shutter cap
            break
        saved = state.uncovered.copy()
        batch, g = state.fill_batch()
        if not batch:
            # nothing fits now: jump to the next window opening of a useful field
            opening = state.next_opening(g)
            if opening is None:
                break
            state.free_at = opening
            continue
        batch, starts = state.time_batch(batch, saved)
        if not batch:
            state.free_at += cfg.time_step_s
            continue
        state.commit(batch, starts)

    observations = sorted(state.observations, key=lambda o: o.start)
    problem.clock.step("greedy", len(problem.field_ids))  # (A3) the budget of the stages after it
    return ScheduleResult(
        observations=tuple(observations),
        solver="greedy",
        status=status,
        mip_gap=None,
        runtime_s=time.perf_counter() - t_wall,
        details={"n_blocks": state.block},
    )


class _Greedy:
    """The greedy walk's state: what is still uncovered, the fields used, the exposures so far, the clock."""

    def __init__(self, problem: PlanningProblem) -> None:
        cfg = problem.config
        self.problem, self.cfg = problem, cfg
        self.exp = cfg.exposure_s
        self.n = len(problem.field_ids)
        self.fp = problem.footprints
        self.w_rows = _window_rows(problem)
        self.w_start, self.w_end = problem.windows.start, problem.windows.end
        self.uncovered = problem.prob.copy()
        self.used = np.zeros(self.n, dtype=bool)
        self.observations: list[Observation] = []
        self.pass_target = max(cfg.cadence_s - cfg.filter_change_s, self.exp)
        self.second_delay = max(cfg.cadence_s, self.pass_target + cfg.filter_change_s) + self.exp + 60.0
        self.free_at = 0.0
        self.previous: tuple[float, float, str] | None = None
        self.block = 0
        self.cap = cfg.max_open_shutter_s  # (S4) open-shutter budget (s); None: no cap
        self.field_s = len(cfg.filters) * self.exp  # open shutter of one field's sequence (s)
        self.spent_s = 0.0  # open shutter of the exposures committed (s)

    def affords(self, n_fields: int) -> bool:
        """(S4) Do ``n_fields`` more fields' sequences stay within the open-shutter cap?"""
        return self.cap is None or self.spent_s + n_fields * self.field_s <= self.cap + 1e-6

    def gains(self) -> np.ndarray:
        """Uncovered probability in each field's footprint."""
        return self.fp.field_probability(self.uncovered)

    def _cover(self, k: int) -> None:
        fp = self.fp
        self.uncovered[fp.indices[fp.indptr[k]:fp.indptr[k + 1]]] = 0.0

    def fill_batch(self) -> tuple[list[int], np.ndarray]:
        """Pick fields by marginal gain until the first-filter pass is long enough; (rows, gains left)."""
        problem, cfg, exp, n = self.problem, self.cfg, self.exp, self.n
        f1 = cfg.filters[0]
        batch: list[int] = []
        t = self.free_at
        prev = self.previous
        g = self.gains()
        while self.affords(len(batch) + 1):
            if prev is None:
                oh = np.zeros(n)
            else:
                oh = overhead_time(prev[0], prev[1], problem.ra, problem.dec, cfg.slew,
                                   cfg.filter_change_s if prev[2] != f1 else 0.0)
            ts = t + oh
            cand = ~self.used & (g > 0) & (ts + exp <= cfg.horizon_s)
            cand &= _observable(self.w_rows, self.w_start, self.w_end, ts, exp, n)
            for p in range(1, len(cfg.filters)):  # each later visit, by estimate
                cand &= _observable(self.w_rows, self.w_start, self.w_end, ts + p * self.second_delay, exp, n)
            if not cand.any():
                break
            k = int(np.argmax(np.where(cand, g, -1.0)))
            batch.append(k)
            self.used[k] = True
            self._cover(k)
            g = self.gains()
            t = ts[k] + exp
            prev = (problem.ra[k], problem.dec[k], f1)
            if t - self.free_at >= self.pass_target:
                break
        return batch, g

    def next_opening(self, g: np.ndarray) -> float | None:
        """When to try again after an empty batch: the next window opening of a useful field (None: none)."""
        n = self.n
        useful = ~self.used & (g > 0)
        useful_windows = (self.w_rows >= 0) & useful[np.clip(self.w_rows, 0, max(n - 1, 0))]
        later = self.w_start[useful_windows & (self.w_start > self.free_at)]
        if later.size == 0:
            return None
        return max(float(later.min()), self.free_at + self.cfg.time_step_s / 2)

    def time_batch(self, batch: list[int], saved: np.ndarray) -> tuple[list[int], np.ndarray]:
        """Time every pass; drop the fields whose real times leave their windows, or whose sequence spans more
        than the pair separation (re-timing the rest)."""
        starts = np.empty((len(self.cfg.filters), 0))
        while batch:
            starts = time_passes(self.problem, batch, self.free_at, self.previous)
            rows = np.asarray(batch)
            ok = starts[-1] + self.exp <= self.cfg.horizon_s
            for pass_starts in starts:
                ok &= _observable_each(self.w_rows, self.w_start, self.w_end, rows, pass_starts, self.exp)
            if len(self.cfg.filters) > 2:  # (F6) a sequence's last visit within the pair separation of its first
                ok &= starts[-1] - starts[0] <= self.cfg.pair_separation_s + 1e-6
            if ok.all():
                break
            bad = [b for b, good in zip(batch, ok) if not good]
            batch = [b for b, good in zip(batch, ok) if good]
            self.used[bad] = False  # they may still fit a later batch
            self.uncovered = saved.copy()
            for k in batch:
                self._cover(k)
        return batch, starts

    def commit(self, batch: list[int], starts: np.ndarray) -> None:
        """Add a timed batch's exposures (every filter of the sequence) as one block and move the clock past it."""
        problem, exp, filters = self.problem, self.exp, self.cfg.filters
        for i, k in enumerate(batch):
            fid = int(problem.field_ids[k])
            ra, dec = float(problem.ra[k]), float(problem.dec[k])
            for band, t in zip(filters, starts[:, i]):
                self.observations.append(Observation(fid, ra, dec, band, float(t), exp, self.block))
        self.spent_s += len(batch) * self.field_s
        last = batch[-1]
        self.free_at = float(starts[-1, -1] + exp)
        self.previous = (float(problem.ra[last]), float(problem.dec[last]), filters[-1])
        self.block += 1


def _observable_each(w_rows: np.ndarray, w_start: np.ndarray, w_end: np.ndarray,
                     rows: np.ndarray, starts: np.ndarray, exposure_s: float) -> np.ndarray:
    """For each (row, start) pair: is ``[start, start + exposure]`` inside a window of that row?"""
    match = w_rows[None, :] == rows[:, None]
    inside = (w_start[None, :] <= starts[:, None]) & (starts[:, None] + exposure_s <= w_end[None, :])
    return np.any(match & inside, axis=1)
