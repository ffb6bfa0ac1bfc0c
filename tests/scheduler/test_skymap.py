"""Reading sky maps: formats, resolution, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from astropy.io import fits

from mushrooms.scheduler_core import SkyMapError, read_skymap

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


def _write_moc(path, order, ipix, probdensity, distmu, distsigma):
    """A multi-order FITS map through ligo.skymap's own writer (DISTNORM consistent)."""
    from astropy.table import Table
    from ligo.skymap.distance import parameters_to_moments
    from ligo.skymap.io import write_sky_map
    from ligo.skymap.moc import nest2uniq

    table = Table({
        "UNIQ": nest2uniq(np.asarray(order, np.int8), np.asarray(ipix, np.int64)),
        "PROBDENSITY": np.asarray(probdensity, float),
        "DISTMU": np.asarray(distmu, float),
        "DISTSIGMA": np.asarray(distsigma, float),
        "DISTNORM": parameters_to_moments(np.asarray(distmu, float), np.asarray(distsigma, float))[2],
    })
    write_sky_map(str(path), table, gps_time=1e9, objid="TEST")
    return path


def test_rasterize_keeps_total_probability_both_ways(tmp_path):
    # base pixel 0 at order 1 (4 pixels), base pixel 1 at order 3 (64 pixels),
    # the other 10 base pixels at order 0; working order 2 between them.
    order = np.r_[np.full(4, 1), np.full(64, 3), np.zeros(10, int)]
    ipix = np.r_[np.arange(4), 64 + np.arange(64), np.arange(2, 12)]
    prob = np.r_[np.full(4, 0.15), np.full(64, 0.4 / 64), np.zeros(10)]
    area = 4 * np.pi / (12 * 4.0**order)
    path = _write_moc(tmp_path / "moc.fits", order, ipix, prob / area, np.full(78, 100.0), np.full(78, 20.0))
    m = read_skymap(path, nside=4)
    assert m.prob.sum() == pytest.approx(1.0, abs=1e-14)
    assert m.prob[:16] == pytest.approx(np.full(16, 0.15 / 4), rel=1e-12)  # shared among 4 children
    assert m.prob[16:32] == pytest.approx(np.full(16, 0.4 / 16), rel=1e-12)  # 4 merged into each
    assert np.all(m.prob[32:] == 0)
    # equal distance posteriors merge and spread to themselves
    assert m.distmu[:32] == pytest.approx(np.full(32, 100.0), rel=1e-9)
    assert m.distsigma[:32] == pytest.approx(np.full(32, 20.0), rel=1e-9)


def _moments(mu, sigma):
    from ligo.skymap.distance import parameters_to_moments

    mean, std, _ = parameters_to_moments(np.asarray(mu, float), np.asarray(sigma, float))
    return mean, std


#: Two distance populations in one working pixel: 30 % near 200 Mpc, 70 % near 250 Mpc.
_NEAR_FAR_WEIGHT = np.array([0.15, 0.15, 0.35, 0.35])
_NEAR_FAR_MU = np.array([200.0, 200.0, 250.0, 250.0])
_NEAR_FAR_SIGMA = np.full(4, 20.0)


def _near_far_moc(path):
    """Base pixel 0 as 4 order-1 pixels holding all the probability; the rest empty."""
    order = np.r_[np.ones(4, int), np.zeros(11, int)]
    ipix = np.r_[np.arange(4), np.arange(1, 12)]
    area = 4 * np.pi / (12 * 4.0**order)
    prob = np.r_[_NEAR_FAR_WEIGHT, np.zeros(11)]
    mu = np.r_[_NEAR_FAR_MU, np.full(11, 100.0)]
    return _write_moc(path, order, ipix, prob / area, mu, np.r_[_NEAR_FAR_SIGMA, np.full(11, 10.0)])


def _near_far_flat(path, nest):
    import healpy as hp

    prob, mu, sigma = np.zeros(48), np.full(48, 100.0), np.full(48, 10.0)
    prob[:4], mu[:4], sigma[:4] = _NEAR_FAR_WEIGHT, _NEAR_FAR_MU, _NEAR_FAR_SIGMA
    from ligo.skymap.distance import parameters_to_moments

    norm = parameters_to_moments(mu, sigma)[2]
    maps = [prob, mu, sigma, norm]
    if not nest:
        maps = [hp.reorder(m, n2r=True) for m in maps]
    hp.write_map(str(path), maps, nest=nest, column_names=["PROB", "DISTMU", "DISTSIGMA", "DISTNORM"],
                 dtype=[np.float64] * 4)
    return path


@pytest.mark.parametrize("write", [_near_far_moc, lambda p: _near_far_flat(p, True),
                                   lambda p: _near_far_flat(p, False)],
                         ids=["multi-order", "flat-nested", "flat-ring"])
def test_merged_pixels_combine_distance_moments_not_parameters(tmp_path, write):
    """The working pixel's ansatz has the mixture's mean and variance.

    Averaging the parameters (the old reader) would give DISTMU 235, DISTSIGMA
    20: a conditional standard deviation near 20 Mpc where the mixture's is 31.
    """
    from ligo.skymap.distance import moments_to_parameters

    m = read_skymap(write(tmp_path / "near_far.fits"), nside=1)
    assert m.prob[0] == pytest.approx(1.0)
    mean_i, std_i = _moments(_NEAR_FAR_MU, _NEAR_FAR_SIGMA)
    w = _NEAR_FAR_WEIGHT / _NEAR_FAR_WEIGHT.sum()
    mean = np.sum(w * mean_i)
    std = np.sqrt(np.sum(w * (std_i**2 + mean_i**2)) - mean**2)
    got_mean, got_std = _moments(m.distmu[0], m.distsigma[0])
    assert got_mean == pytest.approx(mean, rel=1e-9)
    assert got_std == pytest.approx(std, rel=1e-9)
    assert (m.distmu[0], m.distsigma[0], m.distnorm[0]) == pytest.approx(moments_to_parameters(mean, std), rel=1e-9)
    # and not the probability-weighted average of the parameters
    averaged_std = _moments(np.sum(w * _NEAR_FAR_MU), np.sum(w * _NEAR_FAR_SIGMA))[1]
    assert got_std > 1.4 * averaged_std


def _by_hand_reference(path, order):
    """Working-order probability and distance layers of a multi-order map, from
    ligo.skymap's reader and moment functions and NumPy sums (no rasterize)."""
    from ligo.skymap.distance import moments_to_parameters, parameters_to_moments
    from ligo.skymap.io import read_sky_map
    from ligo.skymap.moc import uniq2nest

    t = read_sky_map(str(path), moc=True)
    src_order, ipix = uniq2nest(np.asarray(t["UNIQ"]))
    src_order = src_order.astype(np.int64)
    p = np.asarray(t["PROBDENSITY"]) * 4 * np.pi / (12 * 4.0**src_order)
    with np.errstate(invalid="ignore"):
        mean_i, std_i, _ = parameters_to_moments(np.asarray(t["DISTMU"]), np.asarray(t["DISTSIGMA"]))
    bad = ~np.isfinite(np.asarray(t["DISTMU"]))  # no distance: makes its working pixel unknown too
    mean_i[bad] = std_i[bad] = np.nan
    # a pixel coarser than the working order is shared equally among its children
    children = np.where(src_order < order, 4 ** np.maximum(order - src_order, 0), 1)
    first = np.where(src_order < order, ipix << (2 * np.maximum(order - src_order, 0)), 0)
    each = np.repeat(np.arange(p.size), children)
    rank = np.arange(each.size) - np.repeat(np.cumsum(children) - children, children)
    target = np.where(src_order[each] < order, first[each] + rank,
                      ipix[each] >> (2 * np.maximum(src_order[each] - order, 0)))
    p, mean_i, std_i = p[each] / children[each], mean_i[each], std_i[each]
    npix = 12 * 4**order
    with np.errstate(invalid="ignore", divide="ignore"):
        prob = np.bincount(target, p, minlength=npix)
        mean = np.bincount(target, p * mean_i, minlength=npix) / prob
        second = np.bincount(target, p * (std_i**2 + mean_i**2), minlength=npix) / prob
        std = np.sqrt(second - mean**2)
    return prob, mean, std, moments_to_parameters(mean, std)


@pytest.mark.parametrize("nside", [32, 128])
def test_multiorder_map_matches_ligo_skymap_downsampled(nside):
    """A real BAYESTAR map (orders 4-9) at a working resolution within its
    orders: probability and DISTMU/DISTSIGMA/DISTNORM as ligo.skymap's
    moment functions give them, and what its own rasterize gives."""
    prob, mean, std, (mu, sigma, norm) = _by_hand_reference(MAP_MULTIORDER, nside.bit_length() - 1)
    m = read_skymap(MAP_MULTIORDER, nside=nside)
    np.testing.assert_allclose(m.prob, prob / prob.sum(), rtol=1e-10, atol=1e-300)
    known = np.isfinite(mu)
    assert 0.5 < known.mean() < 1 and np.array_equal(np.isfinite(m.distmu), known)
    got_mean, got_std = _moments(m.distmu[known], m.distsigma[known])
    # ligo.skymap's own moments -> parameters -> moments round trip keeps the
    # mean to 1e-10 and the std to 2e-5 (at the ansatz's edge, std/mean -> 0.577)
    np.testing.assert_allclose(got_mean, mean[known], rtol=1e-7)
    np.testing.assert_allclose(got_std, std[known], rtol=1e-4)
    # the parameters too, where the ansatz is not at its edge (DISTMU << 0:
    # moments_to_parameters is ill-conditioned there, the sums' rounding shows)
    tame = known & (mu > 0)
    assert tame.sum() > 0.5 * known.sum()
    for got, want in ((m.distmu, mu), (m.distsigma, sigma), (m.distnorm, norm)):
        np.testing.assert_allclose(got[tame], want[tame], rtol=1e-6)
    # and what ligo.skymap's own rasterisation gives
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    ref = rasterize(read_sky_map(str(MAP_MULTIORDER), moc=True), order=nside.bit_length() - 1)
    np.testing.assert_allclose(m.prob, np.asarray(ref["PROB"]) / np.sum(ref["PROB"]), rtol=1e-12, atol=1e-300)
    assert np.array_equal(np.isfinite(m.distmu), np.isfinite(np.asarray(ref["DISTMU"])))
    ref_mean, ref_std = _moments(np.asarray(ref["DISTMU"])[known], np.asarray(ref["DISTSIGMA"])[known])
    np.testing.assert_allclose(got_mean, ref_mean, rtol=1e-7)
    np.testing.assert_allclose(got_std, ref_std, rtol=1e-4)  # rasterize's round trip of every pixel


@pytest.mark.parametrize("siblings", ["equal", "distinct"])
@pytest.mark.parametrize("nside", [2, 16])
def test_flat_map_is_what_ligo_skymap_reads_and_rasterises(tmp_path, siblings, nside):
    """A flat map with distance layers, whether most sibling pixels are equal
    (a rasterised multi-order map: ligo.skymap's derasterize route) or none
    are (the one-order route), gives what ``rasterize(read_sky_map(moc=True))``
    gives, coarser (merged by moments) and finer (shared) alike."""
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.distance import parameters_to_moments
    from ligo.skymap.io import read_sky_map, write_sky_map

    rng = np.random.default_rng(7)
    npix = 12 * 4**2  # NSIDE 4
    n_values = npix // 4 if siblings == "equal" else npix
    repeat = npix // n_values
    prob = np.repeat(rng.random(n_values), repeat)
    mu = np.repeat(rng.uniform(100, 300, n_values), repeat)
    sigma = np.repeat(rng.uniform(10, 60, n_values), repeat)
    path = tmp_path / "flat.fits"
    write_sky_map(str(path), [prob / prob.sum(), mu, sigma, parameters_to_moments(mu, sigma)[2]], nest=True,
                  gps_time=1e9)
    ref = rasterize(read_sky_map(str(path), moc=True), order=nside.bit_length() - 1)
    m = read_skymap(path, nside=nside)
    np.testing.assert_allclose(m.prob, np.asarray(ref["PROB"]), rtol=1e-12)
    for got, want in zip(_moments(m.distmu, m.distsigma), _moments(ref["DISTMU"], ref["DISTSIGMA"])):
        np.testing.assert_allclose(got, want, rtol=1e-6)


def test_flat_map_finer_than_working_is_summed_and_coarser_is_shared(tmp_path):
    import healpy as hp

    m128 = read_skymap(MAP_FLAT_RING, nside=128)  # the file's own resolution
    m64 = read_skymap(MAP_FLAT_RING, nside=64)
    m256 = read_skymap(MAP_FLAT_RING, nside=256)
    np.testing.assert_allclose(m64.prob, m128.prob.reshape(-1, 4).sum(axis=1), rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(m256.prob, np.repeat(m128.prob / 4, 4), rtol=1e-12, atol=1e-300)
    assert m64.prob.sum() == pytest.approx(1.0, abs=1e-12) and m256.prob.sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: None, "not found"),
        (lambda p: p.write_bytes(b""), "empty"),
        (lambda p: p.write_bytes(b"hello, I am not a FITS file" * 100), "not a FITS"),
        (lambda p: p.write_bytes(MAP_MULTIORDER.read_bytes()[:20000]), "truncated"),
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


@pytest.mark.parametrize("header", [
    {"OBJECT": "M252714", "DATE-OBS": "2022-07-22T21:57:12.384103", "DISTMEAN": 125.96},
    {"OBJECT": "2", "DATE-OBS": "2012-09-02T03:42:10.277622", "MJD-OBS": 56172.15},
    {"OBJECT": "coinc_event:coinc_event_id:1234"},
    {"OBJECT": 17, "DISTMEAN": 40.0, "DISTSTD": 9.0},
    {},
])
def test_header_metadata_are_ligo_skymaps(header):
    # our reading of the three header keys the plan uses (no ligo.skymap.io import) is ligo.skymap's mapping's
    import itertools

    from ligo.skymap.io.fits import FITS_META_MAPPING

    from mushrooms.scheduler_core.sky.skymap import _metadata

    h = fits.Header(header)
    theirs = {}
    for key, rows in itertools.groupby(FITS_META_MAPPING, lambda row: row[1]):
        if key in h:
            for py_key, _, _, _, from_fits in rows:
                if from_fits is not None:
                    theirs[py_key] = from_fits(h[key])
    ours = _metadata(h)
    assert ours == {k: theirs[k] for k in ("objid", "gps_time", "distmean") if k in theirs}
    assert {type(v) for v in ours.values()} == {type(theirs[k]) for k in ours}


def test_the_map_files_metadata_are_ligo_skymaps():
    from ligo.skymap.io.fits import read_sky_map

    m = read_skymap(MAP_MULTIORDER, nside=64)
    meta = read_sky_map(str(MAP_MULTIORDER), moc=True).meta
    assert m.object_id == str(meta["objid"]) and m.distmean == meta["distmean"]
    assert m.event_time.gps == pytest.approx(meta["gps_time"], abs=1e-6)
