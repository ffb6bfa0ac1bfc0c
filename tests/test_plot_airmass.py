"""The airmass panel's time axis: the night of the exposures, not the whole horizon."""

from __future__ import annotations

import numpy as np

from mushrooms.plot_airmass import _dark_span


def test_the_axis_spans_the_night_holding_the_exposures_not_the_dawn_of_the_start():
    hours = np.arange(0.0, 24.0, 0.1)
    dark = (hours < 0.7) | ((hours >= 15.0) & (hours < 23.5))  # the end of one night, then the next night
    lo, hi = _dark_span(hours, dark, [18.6, 18.7, 20.0, 20.1])
    assert lo == np.float64(15.0) and 23.3 < hi < 23.5


def test_exposures_outside_the_dark_hours_widen_the_axis_and_none_shows_the_longest_night():
    hours = np.arange(0.0, 24.0, 0.1)
    dark = (hours < 0.7) | ((hours >= 15.0) & (hours < 23.5))
    assert _dark_span(hours, dark, [14.0, 14.2, 16.0])[0] == 14.0  # a twilight exposure stays in view
    lo, hi = _dark_span(hours, dark, [])
    assert lo == 15.0 and hi > 23.3
