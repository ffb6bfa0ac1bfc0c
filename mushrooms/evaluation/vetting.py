"""ZTF's vetting rule for a transient candidate: two detections at least 15 minutes apart.

In O4 ZTF's searches "required at least 2 detections separated by at least
15 minutes to select against moving objects" (e.g. GCN Circulars 33848 and
34755, ZTF/GROWTH on S230521k and S230917af).  A single detection is kept
beside it for comparison with the first-release scoring.

Both rules act on a boolean matrix of detections: exposure ``e`` (a done
exposure of the executed record) sees source ``i`` (covered and brighter
than the exposure's limit).  Two detections at least ``Δ`` apart exist iff
the latest detection is at least ``Δ`` after the earliest one, so the rule
is a max-min over each column.
"""

from __future__ import annotations

import numpy as np

__all__ = ["VETTING_SEPARATION_S", "one_detection", "two_detections"]

#: Least separation (s) of the two detections (ZTF's O4 rule).
VETTING_SEPARATION_S = 900.0


def one_detection(seen: np.ndarray) -> np.ndarray:
    """(n,) at least one detection, from (m, n) ``seen``."""
    seen = np.asarray(seen, bool)
    return seen.any(axis=0) if seen.size else np.zeros(seen.shape[-1] if seen.ndim == 2 else 0, bool)


def two_detections(seen: np.ndarray, t_mid_s: np.ndarray, min_separation_s: float = VETTING_SEPARATION_S
                   ) -> np.ndarray:
    """(n,) at least two detections ``min_separation_s`` or more apart (mid-exposure times).

    Parameters
    ----------
    seen : numpy.ndarray
        (m, n) exposure ``e`` detects source ``i``.
    t_mid_s : numpy.ndarray
        (m,) mid-exposure times (s, any origin).
    min_separation_s : float
        Least separation (s).

    Returns
    -------
    numpy.ndarray
        (n,) bool.
    """
    seen = np.asarray(seen, bool)
    t = np.asarray(t_mid_s, float)
    if seen.ndim != 2 or seen.shape[0] != t.size:
        raise ValueError(f"seen must be (m, n) with m = {t.size} exposures, got shape {seen.shape}")
    if seen.shape[0] == 0:
        return np.zeros(seen.shape[1], bool)
    first = np.where(seen, t[:, None], np.inf).min(axis=0)
    last = np.where(seen, t[:, None], -np.inf).max(axis=0)
    return np.isfinite(first) & (last - first >= min_separation_s)
