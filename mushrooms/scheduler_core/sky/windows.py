"""Observability windows: the time intervals (s since the horizon start) in which each field can be observed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Windows", "union_intervals"]


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
