"""Closes chosen for a late or off-speed telescope (Q16-Q18) on a hand-worked night at Palomar.

Two blocks of three 300 s fields near the meridian (Dec 33 deg, 2 deg apart):
each block's g pass, then its r pass opened by Q11 a cadence (1800 s) plus the
margin after the field's g visit, so the telescope idles ~1000 s before each r
pass.  On time the executor takes g at 20/372/719 s and r at 2200/2508/2816 s:
the pairs' least excess over the cadence is ``2816 - 719 - 1800 = 297 s``, so
block 1's g pass gets the tight close ``719 + 297 = 1016 s``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mushrooms.scheduler_core.telescope import execute_queues, queue_set_from_payloads
from mushrooms.scheduler_core.telescope.late_windows import pair_value, robust_closes
from mushrooms.scheduler_core.telescope.queue_windows import time_pass_windows

from test_telescope_executor import EPOCH, LST, TIMING, queue, target

CADENCE = 1800.0
END = 6 * 3600.0


def block(ids, ra0):
    g = [target(i, LST + ra0 + 2 * k, 33.0, 1, 300.0) for k, i in enumerate(ids)]
    return g, [dict(t, filter_id=2) for t in g]


@pytest.fixture(scope="module")
def night():
    g1, r1 = block([201, 202, 203], 0.0)
    g2, r2 = block([204, 205, 206], 8.0)
    qs = queue_set_from_payloads([queue(f"q_{k}", t) for k, t in enumerate([g1, r1, g2, r2], 1)], EPOCH)
    planned = np.array([0, 308, 616, 1920, 2228, 2536, 2900, 3208, 3516, 4820, 5128, 5436], float)
    opens, wide = time_pass_windows(qs, EPOCH, planned, END, CADENCE)
    chosen = robust_closes(qs, EPOCH, opens, wide, np.ones(len(qs)), END, CADENCE)
    return qs, opens, wide, chosen


def play(night, closes, start_s, timing=TIMING):
    qs, opens = night[0], night[1]
    return execute_queues(replace(qs, window_start_s=opens, window_end_s=closes), EPOCH, start_s, END, timing)


def starts(qs, done):
    return {(int(qs.field_id[d.target]), int(qs.filter_id[d.target])): d.start_s for d in done}


def test_a_pass_whose_pairs_a_late_run_squeezes_gets_the_tight_close(night):
    qs, opens, wide, chosen = night
    on_time = starts(qs, play(night, wide, 0.0))
    excess = min(on_time[f, 2] - on_time[f, 1] for f in (201, 202, 203)) - CADENCE
    assert 250.0 < excess < 350.0  # the hand-worked 297 s
    assert chosen[0] == pytest.approx(on_time[203, 1] + excess)  # (Q16) last g start + least excess
    assert wide[0] > chosen[0] + 1500.0  # the wide close would let it run half an hour late


def test_on_time_and_at_the_modelled_speed_the_chosen_closes_change_nothing(night):
    qs, _, wide, chosen = night
    assert play(night, chosen, 0.0) == play(night, wide, 0.0)  # (Q18)
    assert pair_value(qs, play(night, chosen, 0.0), np.ones(len(qs)), CADENCE) == 6.0


def test_half_an_hour_late_the_wide_closes_squeeze_both_blocks_and_the_chosen_keep_the_second(night):
    qs, _, wide, chosen = night
    ones = np.ones(len(qs))
    late = starts(qs, play(night, wide, 1800.0))
    # wide: block 1's g runs 30 min late, its r (open since ~2023 s) follows back to back ...
    assert late[201, 2] - late[201, 1] < 1200.0
    # ... and pushes block 2's g past its pairs' excess: its r follows it below the cadence too
    assert late[204, 2] - late[204, 1] < CADENCE
    assert pair_value(qs, play(night, wide, 1800.0), ones, CADENCE) == 0.0
    # chosen: block 1's g is cut (its time is lost), block 2 runs as planned
    kept = starts(qs, play(night, chosen, 1800.0))
    assert (201, 1) not in kept and kept[204, 2] - kept[204, 1] >= CADENCE
    assert pair_value(qs, play(night, chosen, 1800.0), ones, CADENCE) == 3.0


def test_the_chosen_closes_keep_at_least_what_the_wide_ones_keep_late_or_off_speed(night):
    qs, _, wide, chosen = night
    ones = np.ones(len(qs))
    for start, timing in [(900.0, TIMING), (1800.0, TIMING), (3600.0, TIMING), (0.0, TIMING.scaled(0.8)),
                          (0.0, TIMING.scaled(1.2))]:
        got = pair_value(qs, play(night, chosen, start, timing), ones, CADENCE)
        assert got >= pair_value(qs, play(night, wide, start, timing), ones, CADENCE)
    total = [sum(pair_value(qs, play(night, c, s, t), ones, CADENCE)
                 for s, t in [(900.0, TIMING), (1800.0, TIMING), (3600.0, TIMING), (0.0, TIMING.scaled(0.8)),
                              (0.0, TIMING.scaled(1.2))]) for c in (wide, chosen)]
    assert total[1] > total[0]  # (Q18) chosen for the sum over the scenarios
