"""Field footprints on the sky: the HEALPix pixels inside each field's 16-CCD footprint."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Footprints"]


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
        # a trailing 0 keeps every row start a valid index when the last rows are empty (a field smaller than a
        # pixel holds none); adding 0.0 leaves the last row's sum bit for bit as it was
        values = np.append(prob[self.indices], 0.0)
        sums = np.add.reduceat(values, self.indptr[:-1]) if self.indices.size else np.zeros(len(self.field_ids))
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
