"""What the daemon computes once and reuses for every alert: the warm state.

The ZTF grid, its footprints at the working resolution and the
observability of the whole grid do not depend on the alert.  The
observability is kept per *night*: a 24 h block of grid times starting at
local noon at Palomar (about 19:47 UTC), keyed by the constraints and the
time step.  An alert's windows over ``[start, start + horizon]`` are cut
from the one or two nights its horizon touches (a run of ok grid times is
a window, as in :func:`~mushrooms.scheduler_core.visibility.observability_windows`,
on a grid anchored to the night instead of to the alert), so the second
alert of a night costs no astropy transformation at all.

scheduler_core stays pure: the cache lives here and hands precomputed
pieces to :func:`~mushrooms.scheduler_core.prepare.prepare_problem`.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import OrderedDict
from typing import Any

import numpy as np
from astropy.time import Time, TimeDelta

__all__ = ["SkyCache", "NIGHT_S", "NIGHT_ANCHOR"]

log = logging.getLogger(__name__)

NIGHT_S = 86400.0
#: Local mean noon at Palomar (lon -116.86 deg) on 2000-01-01: nights start here, every 24 h.
NIGHT_ANCHOR = Time("2000-01-01T19:47:26.4", scale="utc")


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
        from ..scheduler_core.fields import load_ztf_fields

        self.grid = load_ztf_fields()
        self._footprints: dict[int, Any] = {}
        self._nights: OrderedDict[tuple[Any, ...], np.ndarray] = OrderedDict()
        self._max_nights = int(max_nights)
        self._lock = threading.Lock()
        self._night_locks: dict[tuple[Any, ...], threading.Lock] = {}
        self.hits = 0
        self.misses = 0

    # ------------------------------------------------------------ footprints
    def footprints(self, nside: int) -> Any:
        """Footprints of the whole grid at ``nside`` (memory, then disk cache)."""
        fp = self._footprints.get(nside)
        if fp is None:
            from ..scheduler_core.fields import field_footprints

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
            from ..scheduler_core.visibility import observing_conditions

            t0 = time.perf_counter()
            j = self._night_steps(config.time_step_s, night)
            times = NIGHT_ANCHOR + TimeDelta(j * config.time_step_s, format="sec")
            mask = observing_conditions(self.grid.ra, self.grid.dec, times, config)
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

    @staticmethod
    def _night_steps(step_s: float, night: int) -> np.ndarray:
        """Grid indices j (times ``NIGHT_ANCHOR + j * step``) of one night."""
        j0 = math.ceil(night * NIGHT_S / step_s - 1e-9)
        j1 = math.ceil((night + 1) * NIGHT_S / step_s - 1e-9)
        return np.arange(j0, j1, dtype=np.int64)

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
        from ..scheduler_core.visibility import windows_from_mask

        step = float(config.time_step_s)
        t_start = float((start - NIGHT_ANCHOR).sec)
        j_first = math.ceil(t_start / step - 1e-9)
        j_last = math.floor((t_start + config.horizon_s) / step + 1e-9)
        n_first = math.floor(j_first * step / NIGHT_S)
        n_last = math.floor(j_last * step / NIGHT_S)
        parts, js = [], []
        for night in range(n_first, n_last + 1):
            j = self._night_steps(step, night)
            sel = (j >= j_first) & (j <= j_last)
            parts.append(self._night_mask(config, night)[:, sel])
            js.append(j[sel])
        ok = np.concatenate(parts, axis=1)
        offsets = np.concatenate(js) * step - t_start
        return windows_from_mask(self.grid.ids, ok, offsets, config.exposure_s)

    # ------------------------------------------------------------ whole problem
    def prepare(self, skymap: Any, config: Any, start: Time) -> Any:
        """:func:`~mushrooms.scheduler_core.prepare.prepare_problem` with the cached pieces."""
        from ..scheduler_core.prepare import prepare_problem

        return prepare_problem(skymap, config, start, grid=self.grid, footprints=self.footprints(config.nside),
                               windows=self.windows(start, config))

    def warm(self, config: Any, now: Time | None = None) -> float:
        """Load footprints and the nights of ``now`` and of the next 24 h; returns the seconds taken."""
        t0 = time.perf_counter()
        now = now or Time.now()
        self.footprints(config.nside)
        self.windows(now, config)
        return time.perf_counter() - t0
