"""The slot MILP's time grid: blocks of ``n`` positions, ``k`` filter passes each (G1, G2).

``docs/design/milp.md``, section "Slot-assignment MILP": position ``q`` of
block ``j`` has its visit in pass ``p`` at ``t_p = T_j + (p - 1) D_n + q s``
with ``D_n = max(n s + t_filt, cadence)`` and ``s = t_exp + t_slew``; a
block lasts ``L_n = (k - 1) D_n + n s + δ t_filt + margin`` (``δ = 0`` when a
sequence of more than two ends in its first filter).  The model on top of
the grid is :mod:`.model`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...config import PlanningConfig
from ...problem import PlanningProblem
from ...sky.windows import union_intervals

__all__ = ["SlotGrid", "PHASES", "block_length_s", "second_pass_delay_s", "n_passes", "observable_segments",
           "make_slot_grid"]

#: Phases of the grid: blocks laid out from each segment's start, or ending at its end.
PHASES = ("start", "end")


def second_pass_delay_s(n: int, config: PlanningConfig) -> float:
    """D_n (s): from a position's start in one filter pass to its start in the next (G1)."""
    s = config.exposure_s + config.slew_estimate_s
    return max(n * s + config.filter_change_s, config.cadence_s)


def n_passes(config: PlanningConfig) -> int:
    """k, the filter passes of a block: one per filter of the sequence."""
    return len(tuple(config.filters))


def _return_change_s(config: PlanningConfig) -> float:
    """The filter change (s) from a block's last pass back to the next block's first (G2): 0 when ``s_k = s_1``."""
    seq = tuple(config.filters)
    return 0.0 if len(seq) > 2 and seq[-1] == seq[0] else config.filter_change_s


def block_length_s(n: int, config: PlanningConfig) -> float:
    """L_n (s): a block of ``n`` positions from its first start to the next block's (G2)."""
    s = config.exposure_s + config.slew_estimate_s
    k = n_passes(config)
    return (k - 1) * second_pass_delay_s(n, config) + n * s + _return_change_s(config) + config.slot_margin_s


def _active_s(n: int, config: PlanningConfig) -> float:
    """From a block's first start to the end of its last exposure (s)."""
    s = config.exposure_s + config.slew_estimate_s
    return (n_passes(config) - 1) * second_pass_delay_s(n, config) + (n - 1) * s + config.exposure_s


@dataclass(frozen=True)
class SlotGrid:
    """Fixed exposure times of every position of every block.

    Attributes
    ----------
    n_positions : int
        n, positions of a full block.
    phase : str
        ``start`` or ``end`` (see :func:`make_slot_grid`).
    block_start : numpy.ndarray
        (J,) T_j (s), in time order.
    block_size : numpy.ndarray
        (J,) positions of block j (n, or fewer for a segment's partial block).
    slot_block, slot_position : numpy.ndarray
        (S,) block j and position q of each slot.
    t1, t2 : numpy.ndarray
        (S,) first- and second-filter exposure starts (s).
    t_later : numpy.ndarray
        (k - 2, S) starts (s) of the passes after the second (G1): empty
        for the pair.
    """

    n_positions: int
    phase: str
    block_start: np.ndarray
    block_size: np.ndarray
    slot_block: np.ndarray
    slot_position: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    t_later: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def pass_starts(self) -> np.ndarray:
        """(k, S) exposure starts (s) of every pass (G1), in sequence order."""
        later = np.asarray(self.t_later, float).reshape(-1, self.t1.size)
        return np.vstack([self.t1, self.t2, later])

    @property
    def n_slots(self) -> int:
        """Number of slots S."""
        return int(self.t1.size)

    @property
    def name(self) -> str:
        """Short label, e.g. ``n6/start``."""
        return f"n{self.n_positions}/{self.phase}"


def observable_segments(problem: PlanningProblem, rows: np.ndarray | None = None) -> list[tuple[float, float]]:
    """Disjoint time intervals (s) in which at least one of the fields is observable.

    Parameters
    ----------
    problem : PlanningProblem
    rows : numpy.ndarray, optional
        Rows of ``problem.field_ids`` to consider (default all).

    Returns
    -------
    list of (start, end)
        In time order, clipped to the horizon.
    """
    w = problem.windows
    sel = np.ones(w.field_ids.size, bool) if rows is None else np.isin(w.field_ids, problem.field_ids[rows])
    starts, ends = union_intervals(np.clip(w.start[sel], 0.0, problem.horizon_s),
                                   np.clip(w.end[sel], 0.0, problem.horizon_s))
    return [(float(s), float(e)) for s, e in zip(starts, ends)]


def make_slot_grid(segments: list[tuple[float, float]], config: PlanningConfig, n: int,
                   phase: str = "start") -> SlotGrid:
    """Cut the observable segments into back-to-back blocks of ``n`` positions.

    Each segment holds as many full blocks as fit (the last exposure of a
    block ends inside the segment) and, in the time left, one partial
    block of the most positions that still fit.  Phase ``start`` lays the
    full blocks out from the segment's start, the partial block last;
    phase ``end`` puts the partial block first and ends the last block at
    the segment's end.

    Parameters
    ----------
    segments : list of (start, end)
        Observable intervals (s), e.g. from :func:`observable_segments`.
    config : PlanningConfig
        Exposure, slew estimate, filter change, cadence and ``slot_margin_s``.
    n : int
        Positions per full block (>= 1).
    phase : str
        ``start`` or ``end``.

    Returns
    -------
    SlotGrid
    """
    if n < 1:
        raise ValueError(f"a block needs at least one position, got n={n}")
    if phase not in PHASES:
        raise ValueError(f"phase must be one of {PHASES}, got {phase!r}")
    s = config.exposure_s + config.slew_estimate_s
    starts: list[float] = []
    sizes: list[int] = []
    for a, b in segments:
        length = b - a
        if length < _active_s(1, config):
            continue
        L = block_length_s(n, config)
        n_full = int(np.floor((length - _active_s(n, config)) / L + 1e-9)) + 1 if length >= _active_s(n, config) else 0
        left = length - n_full * L  # time after the last full block's full length
        partial = 0
        for m in range(n - 1, 0, -1):
            if _active_s(m, config) <= left + 1e-9:
                partial = m
                break
        layout = [n] * n_full + ([partial] if partial else [])
        if phase == "end":
            layout = ([partial] if partial else []) + [n] * n_full
        t = a
        block_t = []
        for m in layout:
            block_t.append(t)
            t += block_length_s(m, config)
        if phase == "end" and layout:
            shift = b - (block_t[-1] + _active_s(layout[-1], config))
            block_t = [x + max(shift, 0.0) for x in block_t]
        starts += block_t
        sizes += layout
    T = np.asarray(starts, float)
    size = np.asarray(sizes, np.int64)
    slot_block = np.repeat(np.arange(T.size), size)
    first = np.concatenate([[0], np.cumsum(size)[:-1]]) if size.size else np.zeros(0, np.int64)
    slot_position = np.arange(int(size.sum())) - np.repeat(first, size)
    delay = np.array([second_pass_delay_s(int(m), config) for m in size]) if size.size else np.zeros(0)
    t1 = T[slot_block] + slot_position * s
    t2 = t1 + delay[slot_block]
    # (G1) the passes after the second, D_n after the one before
    later = t1[None, :] + np.arange(2, n_passes(config))[:, None] * delay[slot_block][None, :]
    return SlotGrid(n, phase, T, size, slot_block, slot_position.astype(np.int64), t1, t2, later)
