"""Issue 53: ``min_gain`` and ``min_coverage`` scale with the area a telescope's field covers (I5).

ZTF's thresholds (0.001 and 0.01 of the probability) hold for a 47.7 deg2
field; a 1 deg2 WINTER field holds about 1/48 of what a ZTF field holds of
the same sky, so with ZTF's numbers it plans nothing on a broad map.  A
description's defaults scale both by the covering detectors' area relative
to ZTF's (``instruments/defaults.py``, ``docs/design/telescopes.md`` I5);
a value the ``[scheduler]`` table sets still wins.
"""

from __future__ import annotations

import numpy as np
import pytest

from mushrooms.scheduler_core import PlanningConfig
from mushrooms.scheduler_core.instruments import load_description
from mushrooms.scheduler_core.instruments.defaults import planning_defaults


def _shoelace_deg2(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _covering_area(name: str) -> float:
    """The detectors behind the planning filters, added up here from the description (not the code under test)."""
    d = load_description(name)
    first = d.planning.filters[0]
    behind = d.filters[first].detectors or tuple(range(len(d.footprint.polygons)))
    return sum(_shoelace_deg2(d.footprint.polygons[i]) for i in behind)


def test_ztf_keeps_its_thresholds_exactly():
    d = planning_defaults(load_description("ztf"))
    assert d["min_gain"] == 0.001 and d["min_coverage"] == 0.01
    assert PlanningConfig.for_telescope(load_description("ztf"), {}) == PlanningConfig()


@pytest.mark.parametrize("name", ["ls4", "winter", "decam"])
def test_thresholds_scale_with_the_covering_area(name):
    ratio = _covering_area(name) / _covering_area("ztf")
    assert 0.01 < ratio < 0.5  # every shipped camera covers less than ZTF's 47.7 deg2
    cfg = PlanningConfig.for_telescope(load_description(name), {})
    assert cfg.min_gain == pytest.approx(0.001 * ratio, rel=5e-3)  # three significant digits
    assert cfg.min_coverage == pytest.approx(0.01 * ratio, rel=5e-3)


def test_winter_thresholds_are_about_one_forty_eighth_of_ztfs():
    cfg = PlanningConfig.for_telescope(load_description("winter"), {})
    assert cfg.min_gain == pytest.approx(0.001 / 47.7, rel=5e-3)
    assert cfg.min_coverage == pytest.approx(0.01 / 47.7, rel=5e-3)


def test_a_set_value_wins_and_the_shipped_ztf_value_does_not():
    winter = load_description("winter")
    cfg = PlanningConfig.for_telescope(winter, {"min_gain": 5e-5, "min_coverage": 0.0})
    assert cfg.min_gain == 5e-5 and cfg.min_coverage == 0.0
    # the shipped config.toml writes ZTF's 0.001 and 0.01 out: not a choice for WINTER
    shipped = PlanningConfig.for_telescope(winter, {"min_gain": 0.001, "min_coverage": 0.01})
    assert shipped.min_gain < 1e-4 and shipped.min_coverage < 1e-3


def test_a_table_naming_winter_first_takes_its_thresholds():
    cfg = PlanningConfig.from_mapping({"telescopes": ["winter", "ztf"]})
    assert cfg.min_gain < 1e-4 and "min_gain" in cfg.record()


def test_a_camera_larger_than_ztfs_keeps_ztfs_thresholds(tmp_path):
    """(I5) The scale is at most 1: a huge (or hostile) footprint never makes min_coverage 1 or more."""
    from mushrooms.scheduler_core.instruments.loader import DATA_DIR

    text = (DATA_DIR / "ls4.toml").read_text().replace('name = "ls4"', 'name = "huge"')
    text = text.replace("detector_width_deg = 0.56889", "detector_width_deg = 25.0")
    text = text.replace("detector_height_deg = 1.13778", "detector_height_deg = 25.0")
    (tmp_path / "huge.toml").write_text(text)
    cfg = PlanningConfig.for_telescope(load_description(str(tmp_path / "huge.toml")), {"nside": 16})
    assert cfg.min_gain == 0.001 and cfg.min_coverage == 0.01
