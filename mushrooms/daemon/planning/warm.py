"""What the daemon computes once and reuses for every alert: the warm state.

The ZTF grid, its footprints at the working resolution and the
observability of the whole grid do not depend on the alert.  The
observability is kept per *night*: a 24 h block of grid times starting at
local noon at Palomar (about 19:47 UTC), keyed by the constraints and the
time step.  An alert's windows over ``[start, start + horizon]`` are cut
from the one or two nights its horizon touches (a run of ok grid times is
a window, as in :func:`~mushrooms.scheduler_core.sky.visibility.observability_windows`,
on a grid anchored to the night instead of to the alert), so the second
alert of a night costs no astropy transformation at all.

scheduler_core stays pure: the cache lives here and hands precomputed
pieces to :func:`~mushrooms.scheduler_core.prepare.prepare_problem`.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections import OrderedDict
from typing import Any, Callable

import numpy as np
from astropy.time import Time, TimeDelta

from ...scheduler_core.sky.visibility import GRID_ANCHOR as NIGHT_ANCHOR
from ...scheduler_core.sky.visibility import NIGHT_S, night_steps

__all__ = ["SkyCache", "warm_up", "warm_plan", "NIGHT_S", "NIGHT_ANCHOR"]

log = logging.getLogger("mushrooms.daemon.warm")
#: the service's own log lines (the warm-up at start)
service_log = logging.getLogger("mushrooms.daemon")


def _visibility_key(config: Any) -> tuple[float, ...]:
    return (config.time_step_s, config.sun_alt_max_deg, config.airmass_max, config.ha_max_h,
            config.moon_sep_min_deg)


class SkyCache:
    """Grid, footprints and per-night observability, computed once and shared.

    Thread-safe: jobs of different superevents call it at the same time; a
    night is computed by one of them while the others wait for it.

    Parameters
    ----------
    max_nights : int
        Nights kept in memory (each ~1.3 MB per configuration at a 120 s step).
    """

    def __init__(self, max_nights: int = 6) -> None:
        from ...scheduler_core.sky.fields import load_ztf_fields

        self.grid = load_ztf_fields()
        self._footprints: dict[int, Any] = {}
        self._nights: OrderedDict[tuple[Any, ...], np.ndarray] = OrderedDict()
        self._max_nights = int(max_nights)
        self._lock = threading.Lock()
        self._night_locks: dict[tuple[Any, ...], threading.Lock] = {}
        self.hits = 0
        self.misses = 0
        #: why the last throw-away plan (:func:`warm_plan`) failed, or None: the service is not ready while set
        self.plan_failure: str | None = None

    # ------------------------------------------------------------ footprints
    def footprints(self, nside: int) -> Any:
        """Footprints of the whole grid at ``nside`` (memory, then disk cache)."""
        fp = self._footprints.get(nside)
        if fp is None:
            from ...scheduler_core.sky.fields import field_footprints

            fp = self._footprints[nside] = field_footprints(self.grid, nside)
        return fp

    # ------------------------------------------------------------ visibility
    def _night_mask(self, config: Any, night: int) -> np.ndarray:
        """(n_grid, m) observability on the night's grid times ``j`` (see :meth:`_grid_index`)."""
        key = (_visibility_key(config), night)
        with self._lock:
            mask = self._nights.get(key)
            if mask is not None:
                self._nights.move_to_end(key)
                self.hits += 1
                return mask
            night_lock = self._night_locks.setdefault(key, threading.Lock())
        with night_lock:  # one thread computes a night; the others wait for it
            with self._lock:
                mask = self._nights.get(key)
            if mask is not None:
                return mask
            from ...scheduler_core.sky.visibility import grid_times, night_epoch, observing_conditions

            t0 = time.perf_counter()
            j = night_steps(config.time_step_s, night)
            mask = observing_conditions(self.grid.ra, self.grid.dec, grid_times(j, config.time_step_s), config,
                                        apparent_epoch=night_epoch(night))
            mask.setflags(write=False)
            with self._lock:
                self.misses += 1
                self._nights[key] = mask
                while len(self._nights) > self._max_nights:
                    self._nights.popitem(last=False)
                self._night_locks.pop(key, None)
            log.info("event=visibility_cached night=%s fields=%d steps=%d seconds=%.2f",
                     (NIGHT_ANCHOR + TimeDelta(night * NIGHT_S, format="sec")).isot[:10], mask.shape[0],
                     mask.shape[1], time.perf_counter() - t0)
            return mask

    def windows(self, start: Time, config: Any) -> Any:
        """Windows of every grid field over ``[start, start + horizon]`` (s since ``start``).

        Parameters
        ----------
        start : astropy.time.Time
            Horizon start (UTC).
        config : PlanningConfig
            Horizon, time step, exposure and the constraints.

        Returns
        -------
        Windows
        """
        from ...scheduler_core.sky.visibility import windows_on_grid

        step = float(config.time_step_s)

        def conditions(night: int, j: np.ndarray) -> np.ndarray:
            return self._night_mask(config, night)[:, j - night_steps(step, night)[0]]

        return windows_on_grid(self.grid.ids, start, config, conditions)

    # ------------------------------------------------------------ whole problem
    def prepare(self, skymap: Any, config: Any, start: Time) -> Any:
        """:func:`~mushrooms.scheduler_core.prepare.prepare_problem` with the cached pieces."""
        from ...scheduler_core.prepare import prepare_problem

        return prepare_problem(skymap, config, start, grid=self.grid, footprints=self.footprints(config.nside),
                               windows=self.windows(start, config))

    def warm(self, config: Any, now: Time | None = None) -> float:
        """Load footprints and the nights of ``now`` and of the next 24 h; returns the seconds taken."""
        t0 = time.perf_counter()
        now = now or Time.now()
        self.footprints(config.nside)
        self.windows(now, config)
        return time.perf_counter() - t0


def warm_up(cache: SkyCache, config: Any, should_stop: Callable[[], bool] | None = None) -> SkyCache:
    """Imports, grid, footprints and tonight's visibility, and one throw-away plan, before the first alert.

    The warm-up is a few steps (:func:`_warm_steps`); ``should_stop`` is asked
    before each, so a stop asked for meanwhile (systemd's SIGTERM) ends it at
    the next step boundary: ``event=warm_up_stopped`` names the step not
    taken, and the warm-up's own ``event=warm_up`` line is not written.

    Parameters
    ----------
    cache : SkyCache
        Warmed for ``config``.
    config : PlanningConfig
        The ``[scheduler]`` section.
    should_stop : callable, optional
        True when the service is stopping.

    Returns
    -------
    SkyCache
        ``cache``.  A failed throw-away plan is never raised: it is logged
        at ERROR and kept in ``cache.plan_failure``, and the service is not
        ready while it is set (``/readyz``'s ``warm_up`` check).  The service
        still starts: the plan runs the first stage of every job on the
        bundled map, so its failure may concern that map only (a broken
        install), and a running service stores every notice and tries every
        job; the re-warm timer tries the plan again (:func:`warm_plan`).
    """
    t0 = time.perf_counter()
    t_cache = 0.0
    for name, step in _warm_steps(cache, config, Time.now()):
        if should_stop is not None and should_stop():
            service_log.info("event=warm_up_stopped before=%s seconds=%.2f reason='stop requested'", name,
                             time.perf_counter() - t0)
            return cache
        step()
        if name.startswith("visibility"):
            t_cache = time.perf_counter() - t0
    service_log.info("event=warm_up cache_s=%.2f total_s=%.2f", t_cache, time.perf_counter() - t0)
    return cache


def _warm_steps(cache: SkyCache, config: Any, now: Time) -> tuple[tuple[str, Callable[[], Any]], ...]:
    """The warm-up's steps, in order, each a few seconds at most: (name, what it does).

    Footprints; the visibility of the night holding ``now`` (one hour's
    horizon), then of the rest of the horizon (the next night); the
    solvers' imports; one throw-away plan of the bundled demo map.
    """
    tonight = dataclasses.replace(config, horizon_h=1.0)
    return (("footprints", lambda: cache.footprints(config.nside)),
            ("visibility_tonight", lambda: cache.windows(now, tonight)),
            ("visibility_horizon", lambda: cache.windows(now, config)),
            ("solver_imports", lambda: _import_solvers(config)),
            ("first_plan", lambda: warm_plan(cache, config)))


def _import_solvers(config: Any) -> None:
    """The first alert must not pay for first imports (checker, greedy, the MILP's HiGHS)."""
    from ...scheduler_core.anytime import FIRST_SOLVER, checked_plan  # noqa: F401
    from ...scheduler_core.planner import run_scheduler  # noqa: F401

    if config.solver != FIRST_SOLVER:
        from ...scheduler_core.schedulers.blocks import schedule as block_schedule  # noqa: F401


def warm_plan(cache: SkyCache, config: Any) -> str | None:
    """One checked greedy plan of the bundled demo map (the first calls of every stage of a job's first plan).

    Parameters
    ----------
    cache : SkyCache
        Its ``plan_failure`` is set to the error, or cleared.
    config : PlanningConfig
        The ``[scheduler]`` section.

    Returns
    -------
    str or None
        The error (``Type: message``), or None when the plan succeeded.
    """
    before = cache.plan_failure
    try:
        from ...bundled import demo_skymap_path
        from ...scheduler_core import read_skymap
        from ...scheduler_core.anytime import FIRST_SOLVER, checked_plan
        from ...scheduler_core.planner import run_scheduler

        skymap = read_skymap(demo_skymap_path(), nside=config.nside)
        problem = cache.prepare(skymap, config, Time.now())
        checked_plan(problem, run_scheduler(problem, FIRST_SOLVER), skymap, FIRST_SOLVER)
    except Exception as exc:  # never raised: the service runs, not ready, and says why
        cache.plan_failure = " ".join(f"{type(exc).__name__}: {exc}".split())[:500]
        service_log.error("event=warm_up_plan_failed error=%r reason='every job may fail the same way: the service "
                          "is not ready until a plan succeeds'", cache.plan_failure)
        return cache.plan_failure
    cache.plan_failure = None
    if before is not None:
        service_log.info("event=warm_up_plan_recovered after=%r", before)
    return None
