"""The statistics of the release's tables (issue 55): bootstrap intervals over events, per-row values, cells.

Shared by :mod:`.release_tables` and :mod:`.matched_tables`.  The bootstrap
resamples events with replacement (``draws`` times, one seeded generator
per statistic, so a table is the same on every run) and takes the 2.5th and
97.5th percentiles of the statistic.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..bench.rows import num

__all__ = ["TIE", "bootstrap_interval", "summary", "metric_values", "interval_text", "cell"]

Record = Mapping[str, Any]

#: Per-event differences within this are ties (coverage and efficiency alike).
TIE = 1e-4


def bootstrap_interval(values: Sequence[float], statistic: Callable[..., Any] = np.mean, draws: int = 2000,
                       seed: int = 0, level: float = 0.95) -> tuple[float, float] | None:
    """Percentile bootstrap interval of ``statistic`` over ``values`` resampled with replacement.

    Parameters
    ----------
    values : sequence of float
        One value per event.
    statistic : callable
        ``statistic(array, axis=1)`` of a (draws, n) array (``np.mean``, ``np.median``).
    draws : int
        Resamples.
    seed : int
        Seed of the generator (same seed, same interval).
    level : float
        Central probability of the interval.

    Returns
    -------
    (float, float) or None
        The interval; None with fewer than two values.
    """
    x = np.asarray(values, dtype=float)
    if x.size < 2:
        return None
    pick = np.random.default_rng(seed).integers(0, x.size, size=(draws, x.size))
    stats = statistic(x[pick], axis=1)
    lo, hi = np.percentile(stats, [50.0 * (1.0 - level), 100.0 - 50.0 * (1.0 - level)])
    return float(lo), float(hi)


def summary(values: Sequence[float], draws: int = 2000, seed: int = 0) -> dict[str, Any]:
    """``n``, ``mean``, ``median`` and their bootstrap 95 % intervals (``mean_ci``, ``median_ci``; None below two)."""
    x = np.asarray(values, dtype=float)
    if not x.size:
        return dict(n=0, mean=None, median=None, mean_ci=None, median_ci=None)
    return dict(n=int(x.size), mean=float(x.mean()), median=float(np.median(x)),
                mean_ci=bootstrap_interval(x, np.mean, draws, seed), median_ci=bootstrap_interval(x, np.median, draws, seed))


def metric_values(rows: Sequence[Record], solver: str, column: str, scale: float = 1.0) -> dict[str, float]:
    """Event -> ``column`` of ``solver`` (times ``scale``), for the events where it has a number."""
    out = {}
    for r in rows:
        if str(r["solver"]) == solver and (v := num(r.get(column))) is not None:
            out[str(r["event"])] = v * scale
    return out


def interval_text(ci: tuple[float, float] | None, digits: int = 3, sign: bool = False) -> str:
    """`` [lo, hi]`` of an interval (empty for None)."""
    if ci is None:
        return ""
    f = "+.{}f".format(digits) if sign else ".{}f".format(digits)
    return f" [{format(ci[0], f)}, {format(ci[1], f)}]"


def cell(s: dict[str, Any], digits: int = 3, sign: bool = False) -> str:
    """``mean [lo, hi] / median [lo, hi]`` of a :func:`summary` (``-`` without values), ``+`` signs if asked."""
    if not s["n"]:
        return "-"
    f = "+.{}f".format(digits) if sign else ".{}f".format(digits)
    return (f"{format(s['mean'], f)}{interval_text(s['mean_ci'], digits, sign)} / "
            f"{format(s['median'], f)}{interval_text(s['median_ci'], digits, sign)}")
