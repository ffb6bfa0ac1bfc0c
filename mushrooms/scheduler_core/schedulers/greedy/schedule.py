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
is dropped and the batch re-timed.  A sequence of three or more visits is cut
instead (F10, ``docs/design/sequences.md``) when the visit that fails is its
third or later and its windows hold that visit nowhere from a cadence after
the visit before to the pair separation after the first: the field keeps its
first visits (its first two cover it, F1).  When nothing is observable, the
clock jumps to the next window opening.
"""

from __future__ import annotations

import time

import numpy as np

from ...config import PlanningConfig
from ...plan.document import Observation
from ...problem import PlanningProblem, ScheduleResult, StopCheck
from ...telescope.mount import altaz_mount
from ...telescope.slew import AltAzMount, overhead_time

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
    mount: AltAzMount | None = None,
    lengths: np.ndarray | None = None,
) -> np.ndarray:
    """Start times (s) of a block: ``rows`` in each filter of the sequence, pass after pass.

    Each exposure starts as soon as the overheads allow; an exposure of a
    later pass also waits until the cadence since the same field's exposure
    in the pass before has passed.  ``lengths`` (default: every pass) gives
    each row's visits, a sequence cut by its windows (F10): a row takes no
    exposure in the passes after them (NaN).

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
    mount : AltAzMount, optional
        (M1) An alt-azimuth mount: slews timed on its axes at their time.
    lengths : numpy.ndarray of int, optional
        (F10) Each row's visits (default: every pass).

    Returns
    -------
    numpy.ndarray
        (k, len(rows)) start times (s): row ``p`` is the pass in ``filters[p]``.
    """
    cfg = problem.config
    exp = cfg.exposure_s
    ra = problem.ra[rows]
    dec = problem.dec[rows]
    starts = np.full((len(cfg.filters), len(rows)), np.nan)
    t = free_at
    prev = previous
    for p, band in enumerate(cfg.filters):
        for i in range(len(rows)):
            if lengths is not None and p >= lengths[i]:
                continue
            if prev is None:
                starts[p, i] = t
            else:
                oh = float(overhead_time(prev[0], prev[1], ra[i], dec[i], cfg.slew,
                                         cfg.filter_change_s if prev[2] != band else 0.0, mount, t))
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
        batch, starts, lengths = state.time_batch(batch, saved)
        if not batch:
            state.free_at += cfg.time_step_s
            continue
        state.commit(batch, starts, lengths)

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
        self.mount = altaz_mount(cfg, problem.start)  # (M1) None: equatorial (ZTF)
        self.exp = cfg.exposure_s
        self.n = len(problem.field_ids)
        self.fp = problem.footprints
        self.w_rows = _window_rows(problem)
        self.w_start, self.w_end = problem.windows.start, problem.windows.end
        self.row_start, self.row_end = _windows_by_row(self.w_rows, self.w_start, self.w_end, self.n)
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
                                   cfg.filter_change_s if prev[2] != f1 else 0.0, self.mount, t)
            ts = t + oh
            cand = ~self.used & (g > 0) & (ts + exp <= cfg.horizon_s)
            cand &= _observable(self.w_rows, self.w_start, self.w_end, ts, exp, n)
            cand &= self._later_visits_fit(ts)
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

    def _later_visits_fit(self, ts: np.ndarray) -> np.ndarray:
        """(n,) by estimate, each field's later visits from ``ts`` fit: the second in a window, each later one
        in a window or (F10) the sequence is cut there, no window holding it."""
        cfg, exp, n, delay = self.cfg, self.exp, self.n, self.second_delay
        ok = np.ones(n, dtype=bool)
        alive = np.ones(n, dtype=bool)  # still has this visit, by estimate
        for p in range(1, len(cfg.filters)):
            inside = _observable(self.w_rows, self.w_start, self.w_end, ts + p * delay, exp, n)
            if p >= 2:
                rows = np.arange(n)
                cut = ~self.next_visit_fits(rows, ts + (p - 1) * delay + cfg.cadence_s, ts + cfg.pair_separation_s)
                ok &= ~alive | inside | cut
            else:
                ok &= inside
            alive &= inside
        return ok

    def next_visit_fits(self, rows: np.ndarray, after: np.ndarray, until: np.ndarray) -> np.ndarray:
        """(F10) for each row: does a window of its field hold an exposure starting in ``[after, until]``
        (s, ending within the horizon)?"""
        rows = np.asarray(rows, dtype=np.int64)
        after = np.asarray(after, float)[:, None]
        until = np.minimum(np.asarray(until, float), self.cfg.horizon_s - self.exp)[:, None]
        t = np.maximum(self.row_start[rows], after)  # the earliest start in each of the row's windows
        return np.any((t <= until) & (t + self.exp <= self.row_end[rows]), axis=1)

    def next_opening(self, g: np.ndarray) -> float | None:
        """When to try again after an empty batch: the next window opening of a useful field (None: none)."""
        n = self.n
        useful = ~self.used & (g > 0)
        useful_windows = (self.w_rows >= 0) & useful[np.clip(self.w_rows, 0, max(n - 1, 0))]
        later = self.w_start[useful_windows & (self.w_start > self.free_at)]
        if later.size == 0:
            return None
        return max(float(later.min()), self.free_at + self.cfg.time_step_s / 2)

    def time_batch(self, batch: list[int], saved: np.ndarray) -> tuple[list[int], np.ndarray, np.ndarray]:
        """Time every pass; drop the fields whose real times leave their windows, or whose sequence spans more
        than the pair separation, or cut such a field's sequence where F10 allows (re-timing the rest).

        Returns the rows kept, their starts (k, m; NaN after a cut sequence's last visit) and their visits (m,).
        """
        k = len(self.cfg.filters)
        lengths = np.full(len(batch), k, dtype=np.int64)
        starts = np.empty((k, 0))
        while batch:
            starts = time_passes(self.problem, batch, self.free_at, self.previous, self.mount, lengths)
            keep, lengths_new = self._fit_sequences(np.asarray(batch), starts, lengths)
            if keep.all() and np.array_equal(lengths_new, lengths):
                break
            bad = [b for b, good in zip(batch, keep) if not good]
            batch = [b for b, good in zip(batch, keep) if good]
            lengths = lengths_new[keep]
            self.used[bad] = False  # they may still fit a later batch
            self.uncovered = saved.copy()
            for r in batch:
                self._cover(r)
        return batch, starts, lengths

    def _fit_sequences(self, rows: np.ndarray, starts: np.ndarray, lengths: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
        """(keep (m,), visits (m,)): each row's first failing visit (outside a window or the horizon, or past
        the pair separation) cuts its sequence there when it is the third or later and no window holds it
        (F10), else drops the row; a cut sequence whose next visit now fits is dropped."""
        cfg, exp = self.cfg, self.exp
        k, m = starts.shape
        fails = np.zeros((k, m), dtype=bool)
        for p in range(k):
            has = p < lengths
            t = np.where(has, starts[p], 0.0)
            inside = _observable_each(self.w_rows, self.w_start, self.w_end, rows, t, exp)
            inside &= t + exp <= cfg.horizon_s
            if p >= 2:  # (F6) a sequence's visits within the pair separation of its first
                inside &= t - starts[0] <= cfg.pair_separation_s + 1e-6
            fails[p] = has & ~inside
        first = np.where(fails.any(axis=0), fails.argmax(axis=0), lengths)
        cut_to = np.minimum(first, lengths)
        keep = cut_to >= min(2, k)
        short = keep & (cut_to < k)
        if short.any():  # (F10) only where no window holds the next visit
            i = np.flatnonzero(short)
            last = starts[cut_to[i] - 1, i]
            fits = self.next_visit_fits(rows[i], last + cfg.cadence_s, starts[0, i] + cfg.pair_separation_s)
            keep[i[fits]] = False
        return keep, np.where(keep, cut_to, lengths)

    def commit(self, batch: list[int], starts: np.ndarray, lengths: np.ndarray) -> None:
        """Add a timed batch's exposures (each field's visits of the sequence) as one block and move the clock
        past it."""
        problem, exp, filters = self.problem, self.exp, self.cfg.filters
        last: tuple[float, int, str] = (-np.inf, -1, filters[0])
        for i, k in enumerate(batch):
            fid = int(problem.field_ids[k])
            ra, dec = float(problem.ra[k]), float(problem.dec[k])
            for band, t in zip(filters[:int(lengths[i])], starts[:, i]):
                self.observations.append(Observation(fid, ra, dec, band, float(t), exp, self.block))
                if t > last[0]:
                    last = (float(t), k, band)
        self.spent_s += float(np.sum(lengths[:len(batch)])) * exp  # (S4) the visits taken (F10 may cut some)
        self.free_at = last[0] + exp
        self.previous = (float(problem.ra[last[1]]), float(problem.dec[last[1]]), last[2])
        self.block += 1


def _observable_each(w_rows: np.ndarray, w_start: np.ndarray, w_end: np.ndarray,
                     rows: np.ndarray, starts: np.ndarray, exposure_s: float) -> np.ndarray:
    """For each (row, start) pair: is ``[start, start + exposure]`` inside a window of that row?"""
    match = w_rows[None, :] == rows[:, None]
    inside = (w_start[None, :] <= starts[:, None]) & (starts[:, None] + exposure_s <= w_end[None, :])
    return np.any(match & inside, axis=1)



def _windows_by_row(w_rows: np.ndarray, w_start: np.ndarray, w_end: np.ndarray, n: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(n, most windows of a row) starts and ends (s) of each row's windows, padded with empty ones (inf, -inf)."""
    valid = np.flatnonzero(w_rows >= 0)
    rows = w_rows[valid]
    order = np.argsort(rows, kind="stable")
    rows, valid = rows[order], valid[order]
    counts = np.bincount(rows, minlength=n)
    pos = np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)
    width = max(int(counts.max()) if counts.size else 0, 1)
    starts, ends = np.full((n, width), np.inf), np.full((n, width), -np.inf)
    starts[rows, pos], ends[rows, pos] = w_start[valid], w_end[valid]
    return starts, ends
