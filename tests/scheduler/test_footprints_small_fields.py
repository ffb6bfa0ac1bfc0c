"""A field smaller than a pixel holds no pixel: its footprint row is empty, and the last rows may be empty too
(WINTER's 1 deg² fields at nside 64 crashed ``mushrooms plan`` in ``field_probability``)."""

from __future__ import annotations

import numpy as np

from mushrooms.scheduler_core.sky.footprints import Footprints


def _footprints(rows: list[list[int]]) -> Footprints:
    indptr = np.cumsum([0] + [len(r) for r in rows])
    return Footprints(nside=1, field_ids=np.arange(1, len(rows) + 1), indptr=indptr,
                      indices=np.array([p for r in rows for p in r], dtype=np.int64))


def test_field_probability_with_empty_rows_at_the_end_and_between() -> None:
    prob = np.arange(12, dtype=float) / 66.0
    fp = _footprints([[0, 1], [], [2, 3, 4], [], []])
    got = fp.field_probability(prob)
    assert got.tolist() == [prob[[0, 1]].sum(), 0.0, prob[[2, 3, 4]].sum(), 0.0, 0.0]


def test_field_probability_of_fields_that_are_all_empty_or_all_full() -> None:
    prob = np.full(12, 1 / 12)
    assert _footprints([[], []]).field_probability(prob).tolist() == [0.0, 0.0]
    assert np.allclose(_footprints([[0], [1, 2]]).field_probability(prob), [1 / 12, 2 / 12])


def test_the_lns_slice_scores_each_candidate_by_its_own_footprint() -> None:
    """(H3) A candidate's gain is the probability in its own footprint, not in the rows up to the next candidate's
    (np.add.reduceat over a subset of row starts summed the rows between candidates into the first)."""
    from mushrooms.scheduler_core.schedulers.portfolio.lns_slice import probability_in_rows

    prob = np.arange(1, 13, dtype=float)
    fp = _footprints([[0, 1], [2], [3, 4, 5], [6], [7, 8]])
    assert probability_in_rows(fp, prob, np.array([0, 2])).tolist() == [1 + 2, 4 + 5 + 6]
    assert probability_in_rows(fp, prob, np.array([3, 1, 4])).tolist() == [7, 3, 8 + 9]
