"""What each planned field brings: its own share of the probability and the coverage after each exposure.

A field's ``probability`` (the document's key) counts the probability inside
its footprint in full, so overlapping fields add up to more than the plan's
coverage.  The *share* divides each pixel's probability equally among the
planned fields that hold it (equation S1 of ``docs/design/plan-format.md``):

    share_f = sum over pixels p in F_f of prob_p / n_p,   n_p = #{planned g : p in F_g}

so the shares of a plan's fields add up to its coverage.  The coverage after
an exposure is the probability inside the union of the fields visited up to
it (S2): it grows with each first visit and ends at the plan's coverage.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..sky.footprints import Footprints

__all__ = ["field_shares", "coverage_after_each"]


def _planned_pixels(footprints: Footprints, field_ids: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of the planned fields' footprints, concatenated, and the position (in ``field_ids``) of each."""
    rows = np.array([footprints.row(int(f)) for f in field_ids], dtype=np.int64)
    starts, ends = footprints.indptr[rows], footprints.indptr[rows + 1]
    lengths = ends - starts
    owner = np.repeat(np.arange(rows.size), lengths)
    offsets = np.arange(int(lengths.sum())) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return footprints.indices[np.repeat(starts, lengths) + offsets], owner


def field_shares(footprints: Footprints, field_ids: Sequence[int], prob: np.ndarray) -> dict[int, float]:
    """Each planned field's own share of the probability (S1; 0-1), summing to the plan's coverage.

    Parameters
    ----------
    footprints : Footprints
        Holds every field of ``field_ids``.
    field_ids : sequence of int
        The planned fields (distinct).
    prob : numpy.ndarray
        Probability per pixel (NESTED, ``footprints.nside``).
    """
    if not len(field_ids):
        return {}
    pixels, owner = _planned_pixels(footprints, field_ids)
    count = np.bincount(pixels, minlength=prob.size)
    share = np.bincount(owner, weights=prob[pixels] / count[pixels], minlength=len(field_ids))
    return {int(f): float(s) for f, s in zip(field_ids, share)}


def coverage_after_each(footprints: Footprints, visits: Sequence[int], prob: np.ndarray) -> np.ndarray:
    """Probability inside the union of the fields visited up to each visit (S2; 0-1).

    Parameters
    ----------
    footprints : Footprints
    visits : sequence of int
        The field of each exposure, in time order (a field may repeat).
    prob : numpy.ndarray
        Probability per pixel.

    Returns
    -------
    numpy.ndarray
        (len(visits),) non-decreasing coverage.
    """
    if not len(visits):
        return np.zeros(0)
    first = list(dict.fromkeys(int(f) for f in visits))  # fields in order of first visit
    pixels, owner = _planned_pixels(footprints, first)
    rank = np.full(prob.size, len(first), dtype=np.int64)
    np.minimum.at(rank, pixels, owner)  # the first visited field holding each pixel
    held = rank < len(first)
    gained = np.cumsum(np.bincount(rank[held], weights=prob[held], minlength=len(first)))
    order = {f: k for k, f in enumerate(first)}
    return gained[np.maximum.accumulate([order[int(f)] for f in visits])]
