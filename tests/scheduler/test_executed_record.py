"""The executed-exposure record of scheduler_core: its checks, the done rule (E1), identity (E2), pairs (E3).

(Named ``test_executed_record`` beside ``tests/handlers/test_executed.py``:
the test directories are not packages, so two test files may not share a name.)
"""

from __future__ import annotations

import numpy as np
import pytest
from astropy.time import Time, TimeDelta

from mushrooms.scheduler_core.errors import InputError
from mushrooms.scheduler_core.executed import (
    MIN_PROCESSED_FRACTION, RECORD_KEYS, ExecutedExposure, done_pairs, from_record, is_done, same_exposure,
    to_record, unique_exposures,
)

T0 = Time("2025-05-14T04:00:00", scale="utc")


def ex(field_id=600, filt="g", minutes=0.0, fraction=1.0, status="processed", exposure_s=300.0):
    return ExecutedExposure(field_id, filt, T0 + TimeDelta(minutes * 60.0, format="sec"), exposure_s, fraction, status)


def test_record_normalises_and_has_an_end():
    e = ExecutedExposure(np.int64(12), "r", Time(T0.mjd, format="mjd", scale="tai"), 30, np.float32(0.5), "processed")
    assert type(e.field_id) is int and e.start.scale == "utc" and e.exposure_s == 30.0
    assert abs((e.end - e.start).to_value("s") - 30.0) < 1e-6


@pytest.mark.parametrize("kwargs, words", [
    (dict(field_id=0), "field_id 0"),
    (dict(field_id=True), "field_id True"),
    (dict(field_id=1.0), "field_id 1.0"),
    (dict(filter="z"), "filter 'z'"),
    (dict(filter="ztfg"), "filter 'ztfg'"),
    (dict(start="2025-05-14T04:00:00"), "not a scalar astropy Time"),
    (dict(start=Time(["2025-05-14T04:00:00"] * 2)), "not a scalar astropy Time"),
    (dict(exposure_s=0), "exposure_s 0"),
    (dict(exposure_s=float("nan")), "not a finite number"),
    (dict(processed_fraction=-0.1), "processed_fraction -0.1"),
    (dict(processed_fraction=None), "not a number"),
    (dict(status="done"), "status 'done'"),
])
def test_record_refuses_values_out_of_range(kwargs, words):
    base = dict(field_id=1, filter="g", start=T0, exposure_s=30.0, processed_fraction=1.0, status="processed")
    with pytest.raises(InputError) as info:
        ExecutedExposure(**{**base, **kwargs})
    assert words in str(info.value)


def test_done_rule_threshold():
    assert MIN_PROCESSED_FRACTION == 0.5  # growth-too-marshal's 32 of 64 quadrants
    assert is_done(ex(fraction=32 / 64)) and not is_done(ex(fraction=31 / 64))
    assert is_done(ex(fraction=0.2), 0.2) and not is_done(ex(fraction=0.2), 0.21)
    assert not is_done(ex(fraction=1.0, status="aborted"))
    assert not is_done(ex(fraction=0.0, status="failed"), 0.0)
    with pytest.raises(ValueError):
        is_done(ex(), 1.5)


def test_identity_is_field_filter_and_start_within_a_second():
    a = ex(minutes=0)
    assert same_exposure(a, ex(minutes=0.9 / 60, fraction=0.3))
    assert not same_exposure(a, ex(minutes=1.1 / 60))
    assert not same_exposure(a, ex(filt="r"))
    assert not same_exposure(a, ex(field_id=601))


def test_unique_keeps_the_most_processed_and_sorts_by_start():
    got = unique_exposures([ex(minutes=10, filt="r"), ex(fraction=0.4), ex(minutes=0.2 / 60, fraction=0.9),
                            ex(minutes=0.4 / 60, fraction=0.9), ex(field_id=601, minutes=5)])
    assert [(e.field_id, e.filter, e.processed_fraction) for e in got] == [
        (600, "g", 0.9), (601, "g", 1.0), (600, "r", 1.0)]
    assert abs((got[0].start - T0).to_value("s") - 0.2) < 1e-6  # the first of the tie
    assert unique_exposures([]) == ()
    assert unique_exposures([ex()]) == (ex(),)


def test_done_pairs():
    records = [
        ex(600, "g", 0), ex(600, "r", 35),            # both
        ex(601, "g", 5), ex(601, "r", 40, 0.2),       # r not done: one (g)
        ex(602, "r", 10), ex(602, "r", 50),           # one filter only (r, first at 10 min)
        ex(603, "g", 15, 0.0, "failed"),              # nothing done
        ex(604, "i", 20),                             # not a filter of the pair
        ex(605, "g", 20), ex(605, "r", 30),           # both, 10 min apart
    ]
    pairs = done_pairs(records)
    assert sorted(pairs.both) == [600, 605]
    assert sorted(pairs.one) == [601, 602]
    assert pairs.one[602].filters == ("r",)
    assert abs((pairs.one[602].earliest - T0).to_value("s") - 600.0) < 1e-6
    assert pairs.both[600].filters == ("g", "r")
    # the cadence: 605's filters are 10 min apart, fewer than 30
    strict = done_pairs(records, cadence_s=1800.0)
    assert sorted(strict.both) == [600] and 605 in strict.one
    # the threshold lets 601's r count
    assert 601 in done_pairs(records, min_processed_fraction=0.2).both
    # a g-i pair
    assert sorted(done_pairs(records, filters=("g", "i")).one) == [600, 601, 604, 605]


@pytest.mark.parametrize("filters", [("g", "g"), ("g", None)])
def test_done_pairs_needs_two_filters(filters):
    with pytest.raises(ValueError):
        done_pairs([], filters=filters)


def test_done_pairs_takes_another_telescopes_two_filters():
    """Any telescope's pair (DECam's i-z, issue 53): a ZTF g-r record holds none of it."""
    assert done_pairs([], filters=("i", "z")).both == {}


def test_record_form_round_trip():
    e = ex(minutes=1.2345)
    rec = to_record(e)
    assert tuple(rec) == RECORD_KEYS and rec["start"].endswith("Z")
    back = from_record(rec)
    assert same_exposure(e, back, tolerance_s=1e-3)
    with pytest.raises(InputError, match="missing key"):
        from_record({"field_id": 1})
    with pytest.raises(InputError, match="not a JSON object"):
        from_record([1])  # type: ignore[arg-type]
