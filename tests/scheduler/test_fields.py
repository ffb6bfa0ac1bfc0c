"""ZTF grid and footprints: area, chip gaps, caching."""

from __future__ import annotations

import healpy as hp
import numpy as np
import pytest

from mushrooms.scheduler_core.fields import (
    ccd_corners, deproject, field_footprints, load_ztf_fields, project,
)


def test_grid_has_1778_fields_primary_and_secondary():
    g = load_ztf_fields()
    assert len(g) == 1778
    assert np.sum(g.ids < 1000) == 881 and np.sum(g.ids > 1000) == 897
    k = g.index_of(np.array([400]))[0]
    assert g.ids[k] == 400
    assert g.index_of(np.array([5000]))[0] == -1


def test_ccd_layout_is_16_ccds_with_gaps():
    c = ccd_corners()
    assert c.shape == (16, 4, 2)
    assert c[..., 0].max() - c[..., 0].min() == pytest.approx(7.29, abs=0.01)
    # the camera centre falls in the cross-shaped gap between CCDs
    assert np.all((np.abs(c[..., 0]) > 0.05).any(axis=1))


def test_footprint_area_is_about_47_deg2_with_chip_gaps():
    g = load_ztf_fields()
    sub = g.select(np.isin(g.ids, [400, 700, 1500]))  # near the equator and at Dec ~ +30
    fp = field_footprints(sub, nside=1024)
    area = np.diff(fp.indptr) * hp.nside2pixarea(1024, degrees=True)
    assert area == pytest.approx([47.0] * 3, abs=1.5)
    # the full camera outline is ~7.29 x 7.46 = 54.4 deg2: chip gaps take ~7 deg2 out
    assert np.all(area < 50.0)
    k = fp.row(400)
    centre = hp.ang2pix(1024, sub.ra[sub.ids == 400][0], sub.dec[sub.ids == 400][0], nest=True, lonlat=True)
    assert centre not in fp.indices[fp.indptr[k]:fp.indptr[k + 1]]  # the boresight is in a gap
    ra_on, dec_on = deproject(np.array([1.0]), np.array([1.0]), sub.ra[sub.ids == 400][0], sub.dec[sub.ids == 400][0])
    on_chip = hp.ang2pix(1024, ra_on[0], dec_on[0], nest=True, lonlat=True)
    assert on_chip in fp.pixels(400)


def test_project_and_deproject_are_inverse():
    x = np.array([-3.5, 0.0, 2.2, 3.6])
    y = np.array([3.7, -1.0, 0.5, -3.7])
    ra, dec = deproject(x, y, 123.4, -25.0)
    x2, y2 = project(ra, dec, 123.4, -25.0)
    assert np.allclose(x, x2, atol=1e-9) and np.allclose(y, y2, atol=1e-9)


def test_footprints_are_cached_on_disk(tmp_path, monkeypatch):
    import mushrooms.scheduler_core.fields as fields

    monkeypatch.setenv("MUSHROOMS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(fields, "_memory_cache", {})
    g = load_ztf_fields()
    sub = g.select(g.ids < 20)
    a = field_footprints(sub, 64)
    files = list(tmp_path.glob("footprints-*.npz"))
    assert len(files) == 1
    monkeypatch.setattr(fields, "_memory_cache", {})
    b = field_footprints(sub, 64)
    assert np.array_equal(a.indices, b.indices) and np.array_equal(a.indptr, b.indptr)
