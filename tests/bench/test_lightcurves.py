"""Light curves: read by band name, interpolate, NaN and out-of-range = not detectable."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mushrooms.scheduler_core.source.lightcurves import (
    LightCurveError,
    load_lightcurve,
    parse_lightcurve,
    read_lightcurve,
)

TEXT = """# t[days] r g
0.5 -15.0 -14.0
1.0 -16.0 -15.0
2.0 nan -13.0
3.0 -14.0 -12.0
"""


@pytest.mark.parametrize(
    "name, g_peak, r_peak",
    [("optimistic", -15.7, -16.0), ("conservative", -15.1, -15.7)],
)
def test_paper_light_curves_have_the_papers_peaks(name: str, g_peak: float, r_peak: float) -> None:
    lc = load_lightcurve(name)
    assert lc.peak("g")[0] == pytest.approx(g_peak, abs=0.06)
    assert lc.peak("r")[0] == pytest.approx(r_peak, abs=0.06)
    # the columns are read by name: u is much fainter than g at its peak time
    t_peak = lc.peak("g")[1]
    assert lc.absolute_mag("u", t_peak) > lc.absolute_mag("g", t_peak) + 0.5


def test_columns_are_read_by_header_name_not_position() -> None:
    lc = parse_lightcurve(TEXT, "t")
    assert lc.bands == ("r", "g")
    assert float(lc.absolute_mag("r", 1.0)) == -16.0
    assert float(lc.absolute_mag("g", 1.0)) == -15.0


def test_linear_interpolation_between_nodes() -> None:
    lc = parse_lightcurve(TEXT, "t")
    assert float(lc.absolute_mag("g", 0.75)) == pytest.approx(-14.5)
    assert float(lc.absolute_mag("g", 2.5)) == pytest.approx(-12.5)
    m = lc.absolute_mag("g", np.array([[0.5, 1.5], [2.0, 3.0]]))
    assert m.shape == (2, 2)
    np.testing.assert_allclose(m, [[-14.0, -14.0], [-13.0, -12.0]])


def test_outside_table_and_nan_are_not_detectable() -> None:
    lc = parse_lightcurve(TEXT, "t")
    m = lc.absolute_mag("g", np.array([0.0, 0.4999, 3.0001, 50.0]))
    assert np.all(np.isposinf(m))
    # r is NaN at 2.0: both neighbouring intervals are unknown, the nodes outside them are fine
    r = lc.absolute_mag("r", np.array([1.0, 1.5, 2.0, 2.5, 3.0]))
    assert float(r[0]) == -16.0 and float(r[-1]) == -14.0
    assert np.all(np.isposinf(r[1:4]))


def test_nsbh_file_nan_entries_are_not_detectable() -> None:
    lc = load_lightcurve("nsbh")
    assert math.isinf(float(lc.absolute_mag("r", lc.t_days[0])))
    assert math.isfinite(float(lc.absolute_mag("g", lc.t_days[0])))


def test_unknown_band_and_bad_files_raise(tmp_path) -> None:
    lc = parse_lightcurve(TEXT, "t")
    with pytest.raises(LightCurveError, match="no band 'z'"):
        lc.absolute_mag("z", 1.0)
    with pytest.raises(LightCurveError, match="header"):
        parse_lightcurve("0.5 1 2\n1.0 1 2\n")
    with pytest.raises(LightCurveError, match="increasing"):
        parse_lightcurve("# t g\n1.0 -15\n0.5 -14\n")
    with pytest.raises(LightCurveError, match="columns"):
        parse_lightcurve("# t g r\n1.0 -15\n2.0 -14\n")
    with pytest.raises(LightCurveError, match="cannot read"):
        read_lightcurve(tmp_path / "missing.dat")


def test_any_file_in_the_format_can_be_given(tmp_path) -> None:
    p = tmp_path / "my_model.dat"
    p.write_text(TEXT)
    lc = load_lightcurve(p)
    assert lc.name == "my_model"
    assert float(lc.absolute_mag("g", 3.0)) == -12.0
