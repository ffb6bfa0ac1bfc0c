"""The P48 slew model."""

from __future__ import annotations

import numpy as np
import pytest

from mushrooms.scheduler_core import SlewModel
from mushrooms.scheduler_core.telescope.slew import axis_time, overhead_time, slew_matrix, slew_time


def test_axis_time_trapezoid_and_triangle():
    # HA axis: 0.4 deg/s2, 2.5 deg/s: top speed after 6.25 s and 7.8 deg; the ramps down and up take 15.6 deg
    assert axis_time(1.0, 0.4, 2.5) == pytest.approx(2 * np.sqrt(1 / 0.4))
    assert axis_time(20.0, 0.4, 2.5) == pytest.approx(20 / 2.5 + 2.5 / 0.4)
    # the switch to cruising is at d = v^2 / a = 15.625 deg, not earlier: 5 and 14 deg are still triangles
    assert axis_time(5.0, 0.4, 2.5) == pytest.approx(2 * np.sqrt(5.0 / 0.4))
    assert axis_time(14.0, 0.4, 2.5) == pytest.approx(2 * np.sqrt(14.0 / 0.4))
    assert axis_time(16.0, 0.4, 2.5) == pytest.approx(16.0 / 2.5 + 2.5 / 0.4)
    # continuous at the switch
    assert axis_time(15.625 - 1e-9, 0.4, 2.5) == pytest.approx(axis_time(15.625 + 1e-9, 0.4, 2.5), rel=1e-6)


def test_slew_is_the_slower_axis_plus_settle_and_wraps_in_ra():
    m = SlewModel()
    t = slew_time(359.0, 0.0, 1.0, 0.0, m)  # 2 deg in HA, across RA = 0
    assert t == pytest.approx(2 * np.sqrt(2 / 0.4) + 1.0)
    t = slew_time(10.0, 0.0, 10.0, 30.0, m)  # pure Dec move
    assert t == pytest.approx(30 / 3.0 + 3.0 / 0.5 + 1.0)
    assert slew_time(5.0, 5.0, 5.0, 5.0, m) == 0.0


def test_overhead_is_readout_slew_or_filter_change_whichever_longest():
    m = SlewModel()
    assert overhead_time(0, 0, 0.1, 0, m) == pytest.approx(8.0)  # readout dominates a tiny slew
    assert overhead_time(0, 0, 60, 0, m, filter_change_s=120.0) == pytest.approx(120.0)
    big = overhead_time(0, 0, 90, 0, m, filter_change_s=0.0)
    assert big == pytest.approx(90 / 2.5 + 2.5 / 0.4 + 1.0)


def test_matrix_is_symmetric_with_zero_diagonal():
    ra = np.array([0.0, 10.0, 200.0])
    dec = np.array([0.0, 40.0, -20.0])
    s = slew_matrix(ra, dec)
    assert np.allclose(s, s.T) and np.all(np.diag(s) == 0) and np.all(s[~np.eye(3, dtype=bool)] >= 8.0)


def test_a_tiny_slew_still_settles_and_the_model_passed_is_used():
    m = SlewModel()
    # 0.05 deg in HA takes 2 sqrt(0.05 / 0.4) = 0.71 s of motion, then the 1 s settle
    assert slew_time(10.0, 0.0, 10.05, 0.0, m) == pytest.approx(2 * np.sqrt(0.05 / 0.4) + 1.0)
    slow = SlewModel(ha_accel_deg_s2=0.1, ha_vmax_deg_s=1.0, settle_s=3.0, readout_s=20.0)
    assert overhead_time(0, 0, 30, 0, slow) == pytest.approx(30 / 1.0 + 1.0 / 0.1 + 3.0)
    assert overhead_time(0, 0, 0.1, 0, slow) == pytest.approx(20.0)
    assert slew_matrix(np.array([0.0, 30.0]), np.array([0.0, 0.0]), slow)[0, 1] == pytest.approx(43.0)
