"""Reading sky maps: formats, resolution, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from astropy.io import fits

from mushrooms.scheduler_core import SkyMapError, read_skymap
from mushrooms.scheduler_core.sky.skymap import rasterize_moc

from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data"
MAP_MULTIORDER = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
MAP_FLAT_RING = DATA / "skymaps" / "S200129m_cWB_RING.fits.gz"


def test_multiorder_map_is_normalised_with_distance_and_time():
    m = read_skymap(MAP_MULTIORDER, nside=128)
    assert m.prob.size == 12 * 128**2
    assert m.prob.sum() == pytest.approx(1.0, abs=1e-12)
    assert m.has_distance and np.nanmax(m.distmu) > 0
    assert m.event_time.isot.startswith("2022-07-22T21:57")
    # 90% area as published for this map (1261.7 deg2), at coarser resolution
    assert m.credible_area(0.9) == pytest.approx(1261.7, rel=0.05)


def test_bytes_and_path_give_the_same_map():
    a = read_skymap(MAP_MULTIORDER, nside=64)
    b = read_skymap(MAP_MULTIORDER.read_bytes(), nside=64)
    assert np.array_equal(a.prob, b.prob)
    assert a.sha256 == b.sha256 and len(a.sha256) == 64


def test_flat_ring_map_is_reordered_to_nested():
    import healpy as hp

    m = read_skymap(MAP_FLAT_RING, nside=128)
    ring = hp.read_map(MAP_FLAT_RING, nest=False)  # the file's own RING values at nside 128
    assert np.allclose(m.prob, hp.reorder(ring / ring.sum(), r2n=True))
    assert not m.has_distance


def test_rasterize_keeps_total_probability_both_ways():
    # one coarse pixel (order 2) and 4 fine ones (order 5) of another coarse pixel
    uniq = np.array([4 * 4**2 + 7] + [4 * 4**5 + i for i in range(4)])
    area2 = 4 * np.pi / (12 * 4**2)
    area5 = 4 * np.pi / (12 * 4**5)
    dens = np.array([0.6 / area2] + [0.1 / area5] * 4)
    prob, _ = rasterize_moc(uniq, dens, order=3)
    assert prob.sum() == pytest.approx(1.0)
    assert prob[7 * 4: 7 * 4 + 4] == pytest.approx([0.15] * 4)  # spread to the 4 children
    assert prob[0] == pytest.approx(0.4)  # the 4 order-5 pixels sum into order-3 pixel 0


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: None, "not found"),
        (lambda p: p.write_bytes(b""), "empty"),
        (lambda p: p.write_bytes(b"hello, I am not a FITS file" * 100), "not a FITS"),
        (lambda p: p.write_bytes(MAP_MULTIORDER.read_bytes()[:20000]), "unreadable"),
    ],
    ids=["missing", "empty", "not-fits", "truncated"],
)
def test_bad_files_raise_one_line_errors(tmp_path, make, message):
    path = tmp_path / "map.fits"
    make(path)
    with pytest.raises(SkyMapError, match=message) as err:
        read_skymap(path)
    assert "\n" not in str(err.value)


def test_map_that_does_not_sum_to_one_is_refused(tmp_path):
    import healpy as hp

    half = np.full(hp.nside2npix(16), 0.5 / hp.nside2npix(16))
    path = tmp_path / "half.fits"
    hp.write_map(path, half, nest=True, column_names=["PROB"], dtype=np.float64)
    with pytest.raises(SkyMapError, match="sum to 0.5"):
        read_skymap(path, nside=16)


def test_negative_probability_is_refused(tmp_path):
    import healpy as hp

    prob = np.full(hp.nside2npix(16), 1.0 / hp.nside2npix(16))
    prob[0] = -prob[0]
    prob[1] += 2 * abs(prob[0])
    path = tmp_path / "neg.fits"
    hp.write_map(path, prob, nest=True, column_names=["PROB"], dtype=np.float64)
    with pytest.raises(SkyMapError, match="non-negative"):
        read_skymap(path, nside=16)
