"""``event.mchirp_source`` (igwn-gwalert-schema 1.3.0): the source-frame chirp mass as binned probabilities.

The field is optional (absent or null in older notices) and informational here: the policy still
decides on the classification and ``HasNS`` (:mod:`~mushrooms.handlers.policy`), and the chirp mass
goes into the decision's reason.  A malformed one never costs the notice: it is left out, with a
note saying why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

__all__ = ["ChirpMass", "parse_mchirp_source"]

#: Most bins read (a longer list is malformed, not a reason to hold a large array).
MAX_BINS = 1000


@dataclass(frozen=True)
class ChirpMass:
    """Source-frame chirp-mass distribution of a CBC candidate.

    Attributes
    ----------
    bin_edges : tuple of float
        Bin edges (solar masses), increasing; one more than ``probabilities``.
    probabilities : tuple of float
        Probability of each bin (0-1).
    """

    bin_edges: tuple[float, ...]
    probabilities: tuple[float, ...]

    def most_likely(self) -> tuple[float, float, float]:
        """(low edge, high edge, probability) of the most probable bin (Msun, Msun, 0-1)."""
        i = max(range(len(self.probabilities)), key=self.probabilities.__getitem__)
        return self.bin_edges[i], self.bin_edges[i + 1], self.probabilities[i]

    def summary(self) -> str:
        """One phrase for a reason, e.g. ``chirp mass 1.05-1.2 Msun (p 0.70)``."""
        lo, hi, p = self.most_likely()
        return f"chirp mass {lo:.3g}-{hi:.3g} Msun (p {p:.2f})"


def _numbers(v: Any, what: str) -> tuple[float, ...]:
    if not isinstance(v, (list, tuple)) or len(v) > MAX_BINS + 1:
        raise ValueError(f"{what} is not a list of at most {MAX_BINS + 1} numbers")
    out = []
    for x in v:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
            raise ValueError(f"{what} holds a value that is not a finite number")
        out.append(float(x))
    return tuple(out)


def parse_mchirp_source(value: Any) -> tuple[ChirpMass | None, str]:
    """Read ``event.mchirp_source``: the distribution, or None and why it was left out.

    Parameters
    ----------
    value : object
        The field as decoded from JSON or Avro (absent and null are None).

    Returns
    -------
    (ChirpMass or None, str)
        The note is empty when the field is absent, null or well formed.
    """
    if value is None:
        return None, ""
    try:
        if not isinstance(value, Mapping):
            raise ValueError(f"it is a {type(value).__name__}, not an object")
        edges = _numbers(value.get("bin_edges"), "bin_edges")
        probs = _numbers(value.get("probabilities"), "probabilities")
        if not probs or len(edges) != len(probs) + 1:
            raise ValueError(f"{len(edges)} bin edges for {len(probs)} probabilities")
        if any(b <= a for a, b in zip(edges, edges[1:])) or edges[0] < 0:
            raise ValueError("bin edges are not increasing from >= 0")
        if any(not 0.0 <= p <= 1.0 + 1e-9 for p in probs) or sum(probs) > 1.0 + 1e-6:
            raise ValueError("probabilities are not in [0, 1] or sum above 1")
    except ValueError as exc:
        return None, f"mchirp_source not used ({exc})"
    return ChirpMass(edges, probs), ""
