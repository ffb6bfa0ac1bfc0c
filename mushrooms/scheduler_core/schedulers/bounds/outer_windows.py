"""Window ends refined below the visibility grid step (V7).

Windows are runs of grid times at which every observing constraint holds
(:mod:`mushrooms.scheduler_core.sky.visibility`), so each end is
conservative by up to one grid step; the certified bounds widen every
window by a whole step (U1, ``docs/design/milp.md`` section 3).  With
300 s exposures and a 120 s step, that is most of an exposure per end.
This module re-evaluates the constraints at ``n_sub - 1`` points inside the
step beyond each end, which tells the two sources of the distance between
the bound and the exact optimum on grid windows apart:

- ``outer``: constraints loosened by 1.1 times the plan checker's tolerances;
  each end moves out to the first point where a loosened constraint fails
  (an exposure touching it is rejected by the checker), else one step as
  in U1.  Every exposure of a checker-accepted plan lies inside these
  windows, so the exact optimum on them bounds every such plan (V7).
- ``inner``: the strict constraints; each end moves out to the last point
  before the first failing one, which a scheduler could plan on (the same
  between-samples argument as the grid's).

Both rest on the grid's own assumption: between two samples a constraint
changes state at most once.  With ``[scheduler] bound_refine_ends = true``
the interval bound (:mod:`.interval_bound`) uses the outer windows instead
of the one-step widening; :mod:`mushrooms.evaluation.true_windows` re-exports
this module for the benchmarks.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from astropy.time import TimeDelta

from ...plan.checker import TOL_AIRMASS, TOL_HA_H, TOL_MOON_DEG, TOL_SUN_DEG
from ...problem import PlanningProblem
from ...sky.constraints import MountLimits, observing_geometry
from ...sky.visibility import keep_out_boxes, site
from ...sky.windows import Windows

__all__ = ["refined_windows", "refined_problem", "N_SUB", "LOOSEN"]

#: Sub-steps per grid step at which the ends are refined (a 120 s step: 15 s).
N_SUB = 8
#: ``outer`` loosens the checker's tolerances by a tenth more: the checker's full astropy geometry and this
#: closed-form one differ by under 1e-3 deg (checker docstring), below a tenth of each tolerance in time.
LOOSEN = 1.1


def _ok(problem: PlanningProblem, rows: np.ndarray, offsets: np.ndarray, loosen: float) -> np.ndarray:
    """(n_rows, n_times) bool: every constraint holds, each loosened by ``loosen`` checker tolerances."""
    cfg = problem.config
    times = problem.start + TimeDelta(offsets, format="sec")
    g = observing_geometry(problem.ra[rows], problem.dec[rows], times, site(cfg.telescope))
    slack = loosen * TOL_HA_H * 15.0
    dec = g.dec_deg[:, None]
    limits = MountLimits(cfg.ha_max_h, keep_out_boxes(cfg))
    mount = limits.allows(g.ha_deg, dec)
    if slack > 0:
        mount = mount | limits.allows(g.ha_deg - slack, dec) | limits.allows(g.ha_deg + slack, dec)
    return ((g.sun_alt_deg <= cfg.sun_alt_max_deg + loosen * TOL_SUN_DEG)[None, :]
            & (g.airmass <= cfg.airmass_max + loosen * TOL_AIRMASS)
            & mount & (g.moon_sep_deg >= cfg.moon_sep_min_deg - loosen * TOL_MOON_DEG))


def refined_windows(problem: PlanningProblem, mode: str = "outer",
                    n_sub: int = N_SUB) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(field_ids, start, end)`` (s) of the problem's windows with refined ends, clipped to the horizon.

    Parameters
    ----------
    problem : PlanningProblem
    mode : {"outer", "inner"}
        See the module docstring.
    n_sub : int
        Sub-steps per grid step.

    Returns
    -------
    tuple of numpy.ndarray
        One row per window of ``problem.windows``, in its order.
    """
    if mode not in ("outer", "inner"):
        raise ValueError(f"mode must be 'outer' or 'inner', not {mode!r}")
    w = problem.windows
    step = problem.config.time_step_s
    H = problem.horizon_s
    fid, s, e = w.field_ids, w.start, w.end
    outer = mode == "outer"
    lo = s - step if outer else s.copy()
    hi = e + step if outer else e.copy()
    if n_sub > 1 and fid.size:
        d = step / n_sub
        j = np.arange(1, n_sub)
        before = s[:, None] - d * j[None, :]  # (n_win, n_sub - 1), nearest first
        after = e[:, None] + d * j[None, :]
        offsets = np.unique(np.clip(np.concatenate([before.ravel(), after.ravel()]), 0.0, H))
        rows_of = {int(f): i for i, f in enumerate(problem.field_ids)}
        uf = np.unique(fid)
        ok = _ok(problem, np.array([rows_of[int(f)] for f in uf]), offsets, LOOSEN if outer else 0.0)
        fr = np.searchsorted(uf, fid)
        n = np.arange(fid.size)
        for side, pts in ((0, before), (1, after)):
            good = ok[fr[:, None], np.searchsorted(offsets, np.clip(pts, 0.0, H))]
            good &= (pts >= 0.0) & (pts <= H)  # no exposure outside the horizon
            bad = ~good
            anybad = bad.any(axis=1)
            first = bad.argmax(axis=1)  # first failing sub-point (0 when none)
            if outer:  # the run holding the window stops before the first failing point
                edge = np.where(anybad, pts[n, first], np.nan)
            else:  # the last passing point before it (the grid end itself when the first one fails)
                last = np.where(anybad, first - 1, n_sub - 2)
                edge = np.where(last >= 0, pts[n, np.maximum(last, 0)], (s, e)[side])
                anybad = np.ones(fid.size, bool)
            if side == 0:
                lo = np.where(anybad, edge, lo)
            else:
                hi = np.where(anybad, edge, hi)
    return fid, np.clip(lo, 0.0, H), np.clip(hi, 0.0, H)


def refined_problem(problem: PlanningProblem, mode: str = "outer") -> PlanningProblem:
    """``problem`` with its windows' ends refined (:func:`refined_windows`)."""
    fid, a, b = refined_windows(problem, mode)
    return dataclasses.replace(problem, windows=Windows(field_ids=fid, start=a, end=b))
