"""Weighted cells: pixels covered by the same set of shortlisted fields, merged.

A pixel's coverage variable in the block MILP only depends on *which*
shortlisted fields contain it, so all pixels with the same membership can
share one variable whose weight is their summed probability.  That turns
hundreds of thousands of pixel variables into a few hundred cells without
changing the optimum.

The membership of every pixel is packed into a bitset (one bit per
shortlisted field, 64 fields per word) and the distinct rows are found with
``numpy.unique``: exact, with no hashing and no loop over pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .footprints import Footprints

__all__ = ["Cells", "merge_cells", "pixel_cells"]


@dataclass(frozen=True)
class Cells:
    """Coverage cells and the fields containing each, as CSR.

    Attributes
    ----------
    weight : numpy.ndarray
        (C,) probability of each cell.
    indptr : numpy.ndarray
        (C+1,) row pointers into ``fields``.
    fields : numpy.ndarray
        Footprint rows (0..n_fields-1) containing each cell, sorted per cell.
    n_pixels : int
        Pixels with probability > 0 inside at least one field (before merging).
    """

    weight: np.ndarray
    indptr: np.ndarray
    fields: np.ndarray
    n_pixels: int

    @property
    def n_cells(self) -> int:
        """Number of cells."""
        return int(self.weight.size)

    def members(self, c: int) -> np.ndarray:
        """Footprint rows containing cell ``c``."""
        return self.fields[self.indptr[c]:self.indptr[c + 1]]


def _pixel_field_pairs(footprints: Footprints, prob: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pixel, row) pairs of every footprint pixel with probability > 0."""
    counts = np.diff(footprints.indptr)
    rows = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    pix = np.asarray(footprints.indices, dtype=np.int64)
    keep = prob[pix] > 0
    return pix[keep], rows[keep]


def _unique_pixels(pix: np.ndarray, npix: int) -> tuple[np.ndarray, np.ndarray]:
    """Sorted distinct pixels and each entry's index among them (a mask: faster than np.unique)."""
    mask = np.zeros(npix, bool)
    mask[pix] = True
    upix = np.flatnonzero(mask)
    index = np.cumsum(mask) - 1
    return upix, index[pix]


def _unique_rows(bits: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows of a bitset matrix and each row's group, sorted like ``np.unique(axis=0)``.

    A random 64-bit key per column word is mixed into one hash per row; rows
    are grouped by hash and the grouping is then verified bit for bit
    against each group's first row, so the result is exact (on a hash
    collision, never seen in practice, it falls back to ``np.unique``).
    """
    rng = np.random.default_rng(0x5EED)
    mult = rng.integers(1, 2**63 - 1, size=bits.shape[1], dtype=np.uint64) | np.uint64(1)
    with np.errstate(over="ignore"):
        h = np.zeros(bits.shape[0], np.uint64)
        for w in range(bits.shape[1]):  # loop over words (n_fields / 64), not pixels
            x = bits[:, w] * mult[w]
            h ^= x ^ (x >> np.uint64(29))
            h *= np.uint64(0x9E3779B97F4A7C15)
    order = np.argsort(h, kind="stable")
    new = np.concatenate([[True], h[order][1:] != h[order][:-1]])
    first = order[new]
    group = np.empty(h.size, np.int64)
    group[order] = np.cumsum(new) - 1
    if not np.array_equal(bits, bits[first[group]]):
        keys, group = np.unique(bits, axis=0, return_inverse=True)
        return keys, group.ravel()
    keys = bits[first]
    # same order as np.unique(axis=0): lexicographic over the words
    order = np.lexsort(keys.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return keys[order], rank[group]


def merge_cells(footprints: Footprints, prob: np.ndarray) -> Cells:
    """Merge pixels covered by exactly the same fields into weighted cells.

    Parameters
    ----------
    footprints : Footprints
        The shortlisted fields (rows are the model's field indices).
    prob : numpy.ndarray
        Probability per pixel (NESTED, same nside).

    Returns
    -------
    Cells
        Cells sorted by their membership bitset; only pixels with positive
        probability inside some field take part.
    """
    pix, rows = _pixel_field_pairs(footprints, prob)
    n_fields = len(footprints.field_ids)
    if pix.size == 0:
        return Cells(np.zeros(0), np.zeros(1, np.int64), np.zeros(0, np.int64), 0)
    upix, pix_idx = _unique_pixels(pix, prob.size)
    n_words = (n_fields + 63) // 64
    bits = np.zeros((upix.size, n_words), dtype=np.uint64)
    # each (pixel, field) pair occurs once, so adding the bits is an OR
    np.add.at(bits, (pix_idx, rows // 64), np.left_shift(np.uint64(1), (rows % 64).astype(np.uint64)))
    keys, cell_of_pixel = _unique_rows(bits)
    weight = np.bincount(cell_of_pixel, weights=prob[upix], minlength=len(keys))
    # decode the bitsets: bit b of word w is field 64 w + b
    shifts = np.arange(64, dtype=np.uint64)
    member = ((keys[:, :, None] >> shifts[None, None, :]) & np.uint64(1)).astype(bool)
    member = member.reshape(len(keys), n_words * 64)[:, :n_fields]
    c_idx, f_idx = np.nonzero(member)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(c_idx, minlength=len(keys)))]).astype(np.int64)
    return Cells(weight, indptr, f_idx.astype(np.int64), int(upix.size))


def pixel_cells(footprints: Footprints, prob: np.ndarray) -> Cells:
    """One cell per pixel (no merging): the model exactly as the appendix writes it.

    Parameters
    ----------
    footprints : Footprints
        The shortlisted fields.
    prob : numpy.ndarray
        Probability per pixel.

    Returns
    -------
    Cells
    """
    pix, rows = _pixel_field_pairs(footprints, prob)
    order = np.lexsort((rows, pix))
    pix, rows = pix[order], rows[order]
    upix, counts = np.unique(pix, return_counts=True)
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return Cells(prob[upix].astype(float), indptr, rows, int(upix.size))
