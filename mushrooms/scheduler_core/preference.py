"""Which of two plans is better: the one rule of the detection stage and of the daemon's supersede.

A plan is summarised here by two published numbers: its coverage ``C``
(probability inside its fields) and, when the map has distance layers, its
expected detections ``E`` (equation X1, a probability too).  The rule
(``docs/design/detection.md``, rules R1-R3):

- (R1) coverage objective, or ``E`` unknown on either plan: the candidate
  is better when it covers at least ``margin`` more (and more at all);
- (R2) detection objective, the ``E`` differ by at least the margin: the
  candidate is better when it expects more and stays above the coverage
  floor;
- (R3) detection objective, the ``E`` differ by less than the margin (a tie,
  e.g. both ~0 for a source too far for the light curve or a stale merger
  clock): coverage decides by (R1).

So a plan is never kept over one with as many expected detections (within
the margin) and more coverage (by the margin).
"""

from __future__ import annotations

__all__ = ["TIE_TOLERANCE", "coverage_is_better", "detections_tie", "is_preferred"]

#: Differences of expected detections at or below this are a tie even with a zero margin
#: (round-off of the X1 sums; 1e-9 of a probability).
TIE_TOLERANCE = 1e-9


def coverage_is_better(c_new: float, c_old: float, margin: float) -> bool:
    """(R1) The candidate covers more, by at least ``margin`` (absolute probability)."""
    gain = float(c_new) - float(c_old)
    return gain > TIE_TOLERANCE and gain >= margin


def detections_tie(e_new: float, e_old: float, margin: float) -> bool:
    """(R3) Expected detections closer than ``margin`` (or than :data:`TIE_TOLERANCE`)."""
    diff = abs(float(e_new) - float(e_old))
    return diff <= TIE_TOLERANCE or diff < float(margin)


def is_preferred(c_new: float, e_new: float | None, c_old: float, e_old: float | None, margin: float,
                 objective: str = "coverage", coverage_floor: float = 0.0) -> bool:
    """True when the candidate ``(c_new, e_new)`` beats the incumbent ``(c_old, e_old)`` (R1-R3).

    Parameters
    ----------
    c_new, c_old : float
        Published coverage of candidate and incumbent (0 to 1).
    e_new, e_old : float or None
        Their expected detections (0 to 1); None without distance layers.
    margin : float
        Least difference that counts (absolute, the same for coverage and
        expected detections: ``[daemon] supersede_min_gain`` when publishing,
        ``[scheduler] min_gain`` inside the detection stage).
    objective : str
        ``coverage`` or ``detection``.
    coverage_floor : float
        (R2) least coverage of a candidate that wins on expected detections
        (X6: ``(1 - ε)`` times the coverage it must not lose much of).

    Returns
    -------
    bool
        Equal plans never replace each other.
    """
    if objective != "detection" or e_new is None or e_old is None:
        return coverage_is_better(c_new, c_old, margin)
    if detections_tie(e_new, e_old, margin):
        return coverage_is_better(c_new, c_old, margin)
    return float(e_new) > float(e_old) and float(c_new) >= float(coverage_floor) - TIE_TOLERANCE
