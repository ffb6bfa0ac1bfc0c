"""Cells over several telescopes' fields, and what a joint plan covers (``docs/design/telescopes.md``, J1, J2, J8).

The cells of one telescope (:mod:`...sky.cells`) merge the pixels covered by
exactly the same fields.  Over several telescopes the same merge runs on
their footprints stacked one telescope after the other: a cell ``l`` is then
the pixels covered by exactly the same fields of all the telescopes, and the
fields holding it, ``S_l``, split by telescope into ``S_{l,τ}`` by the
stacked rows' offsets.  Field ids may repeat across telescopes (two
telescopes on the same grid): the merge works on rows, not ids.

:func:`joint_metrics` measures a joint plan on the map: the union of what
the telescopes cover (each pixel once), each telescope's share (what its
fields cover), its own share (what only it covers) and the probability
covered by more than one telescope.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...problem import PlanningProblem
from ...sky.cells import Cells, merge_cells
from ...sky.footprints import Footprints

__all__ = ["telescope_names", "JointCells", "stack_footprints", "joint_cells", "JointMetrics", "joint_metrics", "covered_pixels"]


def telescope_names(problems: Sequence[PlanningProblem], names: Sequence[str] | None = None) -> tuple[str, ...]:
    """The telescopes' names: ``names`` when given, else each problem's ``telescope`` (``t<i>`` without one),
    numbered when two are the same (``ztf0``, ``ztf1``).

    Raises
    ------
    ValueError
        ``names`` of another length than ``problems``, or repeating a name.
    """
    if names is not None:
        names = tuple(str(n) for n in names)
        if len(names) != len(problems) or len(set(names)) != len(names):
            raise ValueError("one distinct name per telescope's problem")
        return names
    found = [getattr(p, "telescope", None) or f"t{i}" for i, p in enumerate(problems)]
    if len(set(found)) == len(found):
        return tuple(found)
    return tuple(f"{n}{i}" for i, n in enumerate(found))


def stack_footprints(parts: Sequence[Footprints], nside: int) -> tuple[Footprints, np.ndarray]:
    """The footprints of several telescopes one after the other, and each telescope's first row.

    Returns
    -------
    footprints : Footprints
        Rows of telescope ``τ`` are ``offsets[τ] .. offsets[τ + 1] - 1``.
    offsets : numpy.ndarray
        (T + 1,) row offsets.
    """
    sizes = np.array([len(f.field_ids) for f in parts], np.int64)
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    if not parts or offsets[-1] == 0:
        return Footprints(nside, np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.int64)), offsets
    ids = np.concatenate([f.field_ids for f in parts]).astype(np.int64)
    indices = np.concatenate([f.indices for f in parts]).astype(np.int64)
    shift = np.cumsum([0] + [f.indices.size for f in parts[:-1]])
    indptr = np.concatenate([[0]] + [np.asarray(f.indptr[1:], np.int64) + s for f, s in zip(parts, shift)])
    return Footprints(nside, ids, indptr.astype(np.int64), indices), offsets


@dataclass(frozen=True)
class JointCells:
    """Cells over the stacked fields of several telescopes.

    Attributes
    ----------
    cells : Cells
        ``cells.fields`` are stacked rows.
    offsets : numpy.ndarray
        (T + 1,) first stacked row of each telescope.
    """

    cells: Cells
    offsets: np.ndarray

    def telescope_of(self, stacked_rows: np.ndarray) -> np.ndarray:
        """The telescope of each stacked row."""
        return np.searchsorted(self.offsets, np.asarray(stacked_rows, np.int64), side="right") - 1


def joint_cells(parts: Sequence[Footprints], weight: np.ndarray, nside: int) -> JointCells:
    """(J2) Cells ``l`` with weight ``w_l`` over the union of the telescopes' fields ``parts`` (one per telescope)."""
    stacked, offsets = stack_footprints(parts, nside)
    return JointCells(merge_cells(stacked, np.asarray(weight, float)), offsets)


@dataclass(frozen=True)
class JointMetrics:
    """What a joint plan covers (J8), probability of the map (0-1).

    Attributes
    ----------
    union : float
        Covered by any telescope, each pixel once (J1's objective on the map).
    share : tuple of float
        Covered by each telescope's fields.
    own : tuple of float
        Covered by that telescope only.
    more_than_once : float
        Covered by two telescopes or more.
    """

    union: float
    share: tuple[float, ...]
    own: tuple[float, ...]
    more_than_once: float

    def as_dict(self, names: Sequence[str]) -> dict:
        """JSON-ready, telescopes by name, rounded to 1e-6."""
        return {"union": round(self.union, 6), "more_than_once": round(self.more_than_once, 6),
                "share": {n: round(s, 6) for n, s in zip(names, self.share)},
                "own": {n: round(s, 6) for n, s in zip(names, self.own)}}


def covered_pixels(problem: PlanningProblem, field_ids) -> np.ndarray:
    """Pixels inside the given fields of ``problem`` (none for a telescope with no candidate)."""
    ids = [int(f) for f in field_ids]
    if not ids or problem.field_ids.size == 0:
        return np.zeros(0, np.int64)
    return problem.footprints.union(ids)


def joint_metrics(problems: Sequence[PlanningProblem], field_sets: Sequence, prob: np.ndarray) -> JointMetrics:
    """(J8) Union, shares, own shares and the probability covered more than once, of one field set per telescope.

    Parameters
    ----------
    problems : sequence of PlanningProblem
        One per telescope, on the same map and resolution.
    field_sets : sequence
        Field ids each telescope observes.
    prob : numpy.ndarray
        Probability per pixel.
    """
    count = np.zeros(prob.size, np.int32)
    masks = []
    for problem, fields in zip(problems, field_sets):
        pix = covered_pixels(problem, fields)
        masks.append(pix)
        count[pix] += 1
    share = tuple(float(prob[pix].sum()) for pix in masks)
    own = tuple(float(prob[pix[count[pix] == 1]].sum()) for pix in masks)
    union = float(prob[count > 0].sum())
    return JointMetrics(union, share, own, float(prob[count > 1].sum()))
