"""The planning problem every scheduler solves, and what a scheduler returns.

A :class:`PlanningProblem` gathers, once per sky map and start time, all that
the greedy and MILP schedulers need: the observable ZTF fields, their
footprints at the working resolution, their observability windows over the
horizon and the sky map's probability.  Building it is the slow part; the
schedulers themselves are pure functions of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
from astropy.time import Time

from .config import PlanningConfig
from .plan.document import Observation

__all__ = ["Footprints", "Windows", "PlanningProblem", "ScheduleResult", "StopCheck", "union_intervals"]

#: A callable the scheduler polls; True means "stop now, return what you have".
StopCheck = Callable[[], bool]


@dataclass(frozen=True)
class Footprints:
    """HEALPix pixels (NESTED) inside each field's 16-CCD footprint, as CSR.

    Attributes
    ----------
    nside : int
        Resolution of the pixel indices.
    field_ids : numpy.ndarray
        (n,) field IDs, the row order.
    indptr : numpy.ndarray
        (n+1,) row pointers: field k owns ``indices[indptr[k]:indptr[k+1]]``.
    indices : numpy.ndarray
        Pixel indices, sorted within each row.
    """

    nside: int
    field_ids: np.ndarray
    indptr: np.ndarray
    indices: np.ndarray

    def row(self, field_id: int) -> int:
        """Row index of a field ID (KeyError if absent)."""
        rows = np.flatnonzero(self.field_ids == field_id)
        if rows.size == 0:
            raise KeyError(f"field {field_id} not in footprints")
        return int(rows[0])

    def pixels(self, field_id: int) -> np.ndarray:
        """Pixel indices inside one field."""
        k = self.row(field_id)
        return self.indices[self.indptr[k]:self.indptr[k + 1]]

    def union(self, field_ids: Any) -> np.ndarray:
        """Sorted unique pixels inside any of the given fields."""
        ids = np.unique(np.asarray(list(field_ids), dtype=int))
        if ids.size == 0:
            return np.zeros(0, dtype=np.int64)
        rows = np.flatnonzero(np.isin(self.field_ids, ids))
        parts = [self.indices[self.indptr[k]:self.indptr[k + 1]] for k in rows]
        if not parts:
            return np.zeros(0, dtype=np.int64)
        # a mask over the sphere is much faster than np.unique on ~1e6 indices
        mask = np.zeros(12 * self.nside * self.nside, dtype=bool)
        mask[np.concatenate(parts)] = True
        return np.flatnonzero(mask)

    def coverage(self, field_ids: Any, prob: np.ndarray) -> float:
        """Probability inside the union of the given fields' footprints."""
        return float(prob[self.union(field_ids)].sum())

    def field_probability(self, prob: np.ndarray) -> np.ndarray:
        """(n,) probability inside each field on its own."""
        sums = np.add.reduceat(prob[self.indices], self.indptr[:-1]) if self.indices.size else np.zeros(len(self.field_ids))
        empty = self.indptr[1:] == self.indptr[:-1]
        sums = np.asarray(sums, float)
        sums[empty] = 0.0
        return sums

    def subset(self, field_ids: Any) -> "Footprints":
        """Footprints of some fields only, in the order given."""
        ids = np.asarray(list(field_ids), dtype=int)
        rows = [self.row(int(f)) for f in ids]
        parts = [self.indices[self.indptr[k]:self.indptr[k + 1]] for k in rows]
        lengths = np.array([len(p) for p in parts], dtype=np.int64)
        indptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        indices = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        return Footprints(self.nside, ids, indptr, indices)


def union_intervals(start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Disjoint (start, end) intervals covering the union of the given ones, in time order.

    Intervals with ``end <= start`` are ignored; touching ones merge.
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    keep = end > start
    a, b = start[keep], end[keep]
    if a.size == 0:
        return np.zeros(0), np.zeros(0)
    order = np.argsort(a, kind="stable")
    a, b = a[order], b[order]
    reach = np.maximum.accumulate(b)
    new = np.concatenate([[True], a[1:] > reach[:-1]])
    return a[new], np.maximum.reduceat(b, np.flatnonzero(new))


@dataclass(frozen=True)
class Windows:
    """Observability windows: one row per (field, window), several per field.

    Attributes
    ----------
    field_ids : numpy.ndarray
        (m,) field ID of each window.
    start, end : numpy.ndarray
        (m,) window bounds (s since the horizon start).  An exposure
        ``[t, t + exposure]`` is allowed when it lies inside one window.
    """

    field_ids: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def for_field(self, field_id: int) -> list[tuple[float, float]]:
        """The (start, end) windows (s) of one field, in time order."""
        sel = np.flatnonzero(self.field_ids == field_id)
        return sorted((float(self.start[i]), float(self.end[i])) for i in sel)

    def contains(self, field_id: int, t0: float, t1: float) -> bool:
        """True when ``[t0, t1]`` (s) lies inside one window of the field."""
        sel = self.field_ids == field_id
        return bool(np.any((self.start[sel] <= t0) & (t1 <= self.end[sel])))

    def observable_fields(self) -> np.ndarray:
        """Sorted IDs of fields with at least one window."""
        return np.unique(self.field_ids)


@dataclass(frozen=True)
class PlanningProblem:
    """Everything a scheduler needs for one sky map, start time and config.

    Attributes
    ----------
    config : PlanningConfig
        Planning parameters.
    start : astropy.time.Time
        Horizon start (UTC); all times are seconds since it.
    prob : numpy.ndarray
        Sky map probability per pixel (NESTED, ``footprints.nside``).
    field_ids, ra, dec : numpy.ndarray
        Candidate fields (observable at least once in the horizon) and their
        centres (deg), all of the same length.
    footprints : Footprints
        Footprints of the candidate fields, same row order as ``field_ids``.
    windows : Windows
        Observability windows of the candidate fields.
    """

    config: PlanningConfig
    start: Time
    prob: np.ndarray
    field_ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    footprints: Footprints
    windows: Windows

    @property
    def horizon_s(self) -> float:
        """Horizon length (s)."""
        return self.config.horizon_s

    def centre(self, field_id: int) -> tuple[float, float]:
        """(ra, dec) in deg of a candidate field."""
        k = self.footprints.row(field_id)
        return float(self.ra[k]), float(self.dec[k])


@dataclass(frozen=True)
class ScheduleResult:
    """What a scheduler returns, before it becomes a :class:`~.plan.Plan`.

    Attributes
    ----------
    observations : tuple of Observation
        In time order, times in s since the horizon start.
    solver : str
        ``greedy``, ``milp:highs``, ``milp:gurobi``, ...
    status : str
        ``optimal``, ``time_limit``, ``interrupted``, ``greedy``,
        ``no_incumbent_greedy_fallback``, ...
    mip_gap : float or None
        Relative gap at the end (None without a MILP).
    runtime_s : float
        Wall time (s) of this scheduler.
    details : dict
        Free-form diagnostics (model size, bound, retries, ...).
    """

    observations: tuple[Observation, ...]
    solver: str
    status: str
    mip_gap: float | None = None
    runtime_s: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)
