"""ZTF grid and footprints: area, chip gaps, caching."""

from __future__ import annotations

from pathlib import Path

import healpy as hp
import numpy as np
import pytest

from mushrooms.scheduler_core.sky.fields import (
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
    import mushrooms.scheduler_core.sky.fields as fields

    monkeypatch.setenv("MUSHROOMS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(fields, "_memory_cache", {})
    g = load_ztf_fields()
    sub = g.select(g.ids < 20)
    a = field_footprints(sub, 64)
    files = list(tmp_path.glob("footprints-*.npz"))
    assert len(files) == 1
    monkeypatch.setattr(fields, "_memory_cache", {})

    def recompute(*args):
        raise AssertionError("the disk cache was not read")

    monkeypatch.setattr(fields, "_compute_footprints", recompute)
    b = field_footprints(sub, 64)
    assert np.array_equal(a.indices, b.indices) and np.array_equal(a.indptr, b.indptr)
    assert np.array_equal(a.field_ids, b.field_ids) and b.nside == 64


def test_cache_directory_follows_the_environment(monkeypatch, tmp_path):
    from mushrooms.scheduler_core.cachedir import cache_dir  # the footprints' and Earth-orientation caches' folder

    for var in ("MUSHROOMS_CACHE_DIR", "CACHE_DIRECTORY", "XDG_CACHE_HOME"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert cache_dir() == tmp_path / ".cache" / "mushrooms"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_dir() == tmp_path / "xdg" / "mushrooms"
    monkeypatch.setenv("CACHE_DIRECTORY", f"{tmp_path}/systemd:{tmp_path}/other")  # systemd's list
    assert cache_dir() == tmp_path / "systemd"
    monkeypatch.setenv("MUSHROOMS_CACHE_DIR", str(tmp_path / "ours"))
    assert cache_dir() == tmp_path / "ours"


def test_index_of_does_not_assume_sorted_ids():
    g = load_ztf_fields()
    rev = type(g)(g.ids[::-1].copy(), g.ra[::-1].copy(), g.dec[::-1].copy())
    rows = rev.index_of(np.array([400, 1, 1897, 5000]))
    assert rev.ids[rows[:3]].tolist() == [400, 1, 1897] and rows[3] == -1


# ---------------------------------------------------------------- outside references

REF = Path(__file__).resolve().parents[1] / "data" / "ztf"


def _quadrants():
    """(16 CCDs, 4 quadrants, 4 corners, 2) from ztffields' quadrant table (column Quad is the rcid 0-63)."""
    rows = np.loadtxt(REF / "ztf_ccd_quad_layout.tbl", delimiter=",", skiprows=1)
    out = np.zeros((16, 4, 4, 2))
    for ccd in range(1, 17):
        for q in range(4):
            out[ccd - 1, q] = rows[(rows[:, 2] == ccd) & (rows[:, 3] == 4 * (ccd - 1) + q), :2]  # rcid
    return out


def test_ccd_outlines_are_the_union_of_quadrants():
    """Each CCD's corners (ztf_ccd_layout.tbl) are the outer corners of four quadrants of the quadrant table.

    The two tables number the CCDs differently (the quadrant table counts from the other East-West
    side), so outlines are matched by position, and the matching must be one to one.
    """
    quads = _quadrants().reshape(16, 16, 2)  # per quadrant-table CCD: its 16 quadrant corners
    boxes = np.concatenate([quads.min(axis=1), quads.max(axis=1)], axis=1)  # (16, 4): x0, y0, x1, y1
    matched = []
    for corners in ccd_corners():
        box = np.concatenate([corners.min(axis=0), corners.max(axis=0)])
        err = np.abs(boxes - box).max(axis=1)
        matched.append(int(np.argmin(err)))
        assert err.min() < 2e-3, err.min()  # deg: 7 arcsec, 2 pixels
        d = np.linalg.norm(corners[:, None, :] - quads[matched[-1]][None, :, :], axis=-1).min(axis=1)
        assert d.max() < 2e-3  # every corner is a quadrant corner
    assert sorted(matched) == list(range(16))


def test_footprints_match_the_quadrant_layout_pixel_for_pixel():
    """Pixels on any of the 64 quadrants (tested here by plain plane geometry) are the field's footprint."""
    nside = 512
    quads = _quadrants().reshape(64, 4, 2)
    g = load_ztf_fields()
    for fid in (396, 687, 1300, 881):
        k = g.index_of(np.array([fid]))[0]
        ra0, dec0 = np.radians(g.ra[k]), np.radians(g.dec[k])
        vec = hp.ang2vec(g.ra[k], g.dec[k], lonlat=True)
        cand = hp.query_disc(nside, vec, np.radians(5.5), nest=True)
        ra, dec = np.radians(np.array(hp.pix2ang(nside, cand, nest=True, lonlat=True)))
        x = np.degrees(-np.cos(dec) * np.sin(ra - ra0))  # orthographic offsets, as the layout defines them
        y = np.degrees(np.cos(dec0) * np.sin(dec) - np.sin(dec0) * np.cos(dec) * np.cos(ra - ra0))
        inside = np.zeros(cand.size, bool)
        for q in quads:
            (x0, y0), (x1, y1) = q.min(axis=0), q.max(axis=0)  # quadrants are squares to 1e-3 deg
            inside |= (x > x0) & (x < x1) & (y > y0) & (y < y1)
        expected = set(cand[inside].tolist())
        got = set(field_footprints(g.select(g.ids == fid), nside).pixels(fid).tolist())
        assert len(got ^ expected) <= 0.01 * len(expected), (fid, len(got ^ expected), len(expected))
        assert abs(len(got) - len(expected)) <= 0.005 * len(expected)


def test_camera_outline_on_the_sky_agrees_with_ztfs_field_corners():
    """ZTF's measured on-sky camera outlines (ztf_field_corners.csv) against the layout deprojected here."""
    import csv

    g = load_ztf_fields()
    c = ccd_corners()
    outer = np.array([[c[..., 0].min(), c[..., 1].min()], [c[..., 0].min(), c[..., 1].max()],
                      [c[..., 0].max(), c[..., 1].max()], [c[..., 0].max(), c[..., 1].min()]])
    with open(REF / "ztf_field_corners_subset.csv") as f:
        rows = [r for r in csv.reader(f)][1:]
    assert len(rows) == 9
    for r in rows:
        fid, pub = int(r[0]), np.array(r[1:], float).reshape(4, 2)
        k = g.index_of(np.array([fid]))[0]
        ra, dec = deproject(outer[:, 0], outer[:, 1], g.ra[k], g.dec[k])
        ours = hp.ang2vec(ra, dec, lonlat=True)
        theirs = hp.ang2vec(pub[:, 0], pub[:, 1], lonlat=True)
        sep = np.degrees(np.arccos(np.clip(theirs @ ours.T, -1, 1)))
        # every published corner has one of ours within 4.5 arcmin (the published outline is ~1 % larger) ...
        assert sep.min(axis=1).max() < 0.075, (fid, sep.min(axis=1))
        # ... and the two outlines share their centre to 1 arcmin, whatever the declination
        centre = lambda v: v.sum(axis=0) / np.linalg.norm(v.sum(axis=0))  # noqa: E731
        assert np.degrees(np.arccos(min(1.0, centre(ours) @ centre(theirs)))) < 1 / 60, fid
        # the published outline holds all of ours: each of our corners is nearer the centre than theirs
        r_ours = np.degrees(np.arccos(np.clip(ours @ centre(theirs), -1, 1)))
        r_theirs = np.degrees(np.arccos(np.clip(theirs @ centre(theirs), -1, 1)))
        assert r_ours.max() < r_theirs.min(), fid
