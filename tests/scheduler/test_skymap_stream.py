"""The streaming sky-map reader: ligo.skymap's meaning, any layout, bounded memory, bombs refused.

Maps are made here, small (NSIDE 16-256), from the bundled BAYESTAR
multi-order map (rasterised by ligo.skymap) or from seeded random layers
(siblings all different: every merged pixel goes through the moments).
"""

from __future__ import annotations

import gzip
import hashlib
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest
from astropy.io import fits

from mushrooms.scheduler_core import SkyMapError, read_skymap
from mushrooms.scheduler_core.sky.sniff import sniff_fits

DATA = Path(__file__).resolve().parents[1] / "data"
MAP_MULTIORDER = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"
COLUMNS = ("PROB", "DISTMU", "DISTSIGMA", "DISTNORM")


def _moments(mu, sigma):
    from ligo.skymap.distance import parameters_to_moments

    mean, std, _ = parameters_to_moments(np.asarray(mu, float), np.asarray(sigma, float))
    return mean, std


def _rasterised(order: int) -> dict[str, np.ndarray]:
    """The bundled multi-order map as flat NESTED layers at ``order`` (ligo.skymap's rasterize)."""
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    t = rasterize(read_sky_map(str(MAP_MULTIORDER), moc=True), order=order)
    return {c: np.asarray(t[c], float) for c in COLUMNS}


def _noisy(order: int, seed: int = 3) -> dict[str, np.ndarray]:
    """Random layers, no two siblings alike, one pixel without a distance (ligo.skymap's (inf, 1, 0))."""
    from ligo.skymap.distance import parameters_to_moments

    rng = np.random.default_rng(seed)
    n = 12 * 4**order
    prob = rng.random(n) ** 4
    mu, sigma = rng.uniform(50, 400, n), rng.uniform(5, 150, n)
    mu[5], sigma[5] = np.inf, 1.0
    norm = parameters_to_moments(mu, sigma)[2]
    norm[5] = 0.0
    return {"PROB": prob / prob.sum(), "DISTMU": mu, "DISTSIGMA": sigma, "DISTNORM": norm}


def _write_flat(path: Path, layers: dict[str, np.ndarray], nest: bool = True, per_row: int = 1,
                packed: bool = False, header: dict | None = None, fmt: str = "D") -> Path:
    """A flat HEALPix FITS map written with astropy (NESTED or RING, ``per_row`` pixels a row)."""
    import healpy as hp

    npix = next(iter(layers.values())).size
    nside = hp.npix2nside(npix)
    cols = []
    for name, values in layers.items():
        v = values if nest else hp.reorder(values, n2r=True)
        cols.append(fits.Column(name=name, format=f"{per_row}{fmt}" if per_row > 1 else fmt,
                                array=v.reshape(-1, per_row) if per_row > 1 else v))
    hdu = fits.BinTableHDU.from_columns(cols)
    hdu.header.update({"PIXTYPE": "HEALPIX", "ORDERING": "NESTED" if nest else "RING", "COORDSYS": "C",
                       "NSIDE": nside, "INDXSCHM": "IMPLICIT", "OBJECT": "MS220722v",
                       "DATE-OBS": "2022-07-22T21:57:01.000"})
    hdu.header.update(header or {})
    hdus = fits.HDUList([fits.PrimaryHDU(), hdu])
    if packed:
        import io

        buf = io.BytesIO()
        hdus.writeto(buf)
        path.write_bytes(gzip.compress(buf.getvalue()))
    else:
        hdus.writeto(path)
    return path


def _ligo_reference(path: Path, order: int):
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    return rasterize(read_sky_map(str(path), moc=True), order=order)


def _assert_as_ligo(m, ref, mean_rtol=1e-7, std_rtol=1e-4):
    np.testing.assert_allclose(m.prob, np.asarray(ref["PROB"]) / np.sum(ref["PROB"]), rtol=1e-10, atol=1e-300)
    known = np.isfinite(np.asarray(ref["DISTMU"]))
    assert np.array_equal(np.isfinite(m.distmu), known)
    got, want = _moments(m.distmu[known], m.distsigma[known]), _moments(np.asarray(ref["DISTMU"])[known],
                                                                         np.asarray(ref["DISTSIGMA"])[known])
    np.testing.assert_allclose(got[0], want[0], rtol=mean_rtol)
    np.testing.assert_allclose(got[1], want[1], rtol=std_rtol)


# ---------------------------------------------------------------- ligo.skymap's meaning
@pytest.mark.parametrize("nest", [True, False], ids=["nested", "ring"])
@pytest.mark.parametrize("work_nside", [32, 128, 512], ids=["coarser", "same", "finer"])
def test_rasterised_flat_map_reads_as_ligo_skymap_reads_and_rasterises_it(tmp_path, nest, work_nside):
    """A BAYESTAR map rasterised to flat NSIDE 128 with four columns."""
    path = _write_flat(tmp_path / "flat.fits", _rasterised(7), nest=nest)
    m = read_skymap(path, nside=work_nside)
    _assert_as_ligo(m, _ligo_reference(path, work_nside.bit_length() - 1))
    assert m.object_id == "MS220722v" and m.event_time.isot.startswith("2022-07-22T21:57:01")


@pytest.mark.parametrize("nest", [True, False], ids=["nested", "ring"])
def test_noisy_flat_map_merges_by_moments_as_ligo_skymap(tmp_path, nest):
    """Every working pixel merges 16 different children (NSIDE 64 -> 16), one without a distance."""
    path = _write_flat(tmp_path / "noisy.fits", _noisy(6), nest=nest)
    m = read_skymap(path, nside=16)
    _assert_as_ligo(m, _ligo_reference(path, 4))
    assert not np.isfinite(m.distmu[5 >> 4]) and m.distnorm[0] == 0  # the child without a distance


def test_multiorder_map_matches_ligo_skymap_gzip_and_chunks(tmp_path):
    packed = tmp_path / "moc.fits.gz"
    packed.write_bytes(gzip.compress(MAP_MULTIORDER.read_bytes()))
    ref = _ligo_reference(MAP_MULTIORDER, 6)
    whole = read_skymap(MAP_MULTIORDER, nside=64)
    _assert_as_ligo(whole, ref)
    for m in (read_skymap(packed, nside=64), read_skymap(MAP_MULTIORDER, nside=64, chunk=997)):
        np.testing.assert_allclose(m.prob, whole.prob, rtol=1e-12, atol=1e-300)
        np.testing.assert_allclose(m.distmu, whole.distmu, rtol=1e-12)
        np.testing.assert_allclose(m.distsigma, whole.distsigma, rtol=1e-12)


# ---------------------------------------------------------------- layout invariance
def test_nested_ring_gzip_rows_and_chunk_size_give_the_same_map(tmp_path):
    layers = _noisy(6, seed=11)
    ref = read_skymap(_write_flat(tmp_path / "n.fits", layers), nside=16)
    variants = {
        "ring": read_skymap(_write_flat(tmp_path / "r.fits", layers, nest=False), nside=16),
        "gzip": read_skymap(_write_flat(tmp_path / "n.fits.gz", layers, packed=True), nside=16),
        "ring gzip": read_skymap(_write_flat(tmp_path / "r.fits.gz", layers, nest=False, packed=True), nside=16),
        "1024 a row": read_skymap(_write_flat(tmp_path / "n1024.fits", layers, per_row=1024), nside=16),
        "ring 1024 a row, chunk 3000": read_skymap(
            _write_flat(tmp_path / "r1024.fits", layers, nest=False, per_row=1024), nside=16, chunk=3000),
        "chunk 61": read_skymap(tmp_path / "n.fits", nside=16, chunk=61),
        "chunk 4097": read_skymap(tmp_path / "r.fits", nside=16, chunk=4097),
        "bytes": read_skymap((tmp_path / "r.fits.gz").read_bytes(), nside=16),
    }
    for what, m in variants.items():
        np.testing.assert_allclose(m.prob, ref.prob, rtol=1e-12, atol=1e-300, err_msg=what)
        # sums in another order: the moments agree to the tolerance of ligo.skymap's
        # moments_to_parameters solve (mean 1e-7, std 1e-4, as against rasterize itself)
        known = np.isfinite(ref.distmu)
        assert np.array_equal(np.isfinite(m.distmu), known), what
        got, want = _moments(m.distmu[known], m.distsigma[known]), _moments(ref.distmu[known], ref.distsigma[known])
        np.testing.assert_allclose(got[0], want[0], rtol=1e-7, err_msg=what)
        np.testing.assert_allclose(got[1], want[1], rtol=1e-4, err_msg=what)


def test_float32_columns_and_a_map_without_distance_read(tmp_path):
    layers = _rasterised(6)
    single = read_skymap(_write_flat(tmp_path / "e.fits", layers, fmt="E"), nside=64)
    double = read_skymap(_write_flat(tmp_path / "d.fits", layers), nside=64)
    np.testing.assert_allclose(single.prob, double.prob, rtol=1e-6, atol=1e-12)
    prob_only = read_skymap(_write_flat(tmp_path / "p.fits", {"PROB": layers["PROB"]}), nside=64)
    assert not prob_only.has_distance and np.array_equal(prob_only.prob, double.prob)


def test_unsigned_uniq_column_reads_as_signed(tmp_path):
    """Old ligo.skymap wrote UNIQ as an unsigned integer (TZERO = 2^63)."""
    from astropy.table import Table

    t = Table.read(MAP_MULTIORDER, format="fits")
    t["UNIQ"] = np.asarray(t["UNIQ"], np.uint64)
    path = tmp_path / "unsigned.fits"
    t.write(path)
    assert fits.getheader(path, 1).get("TZERO1") == 2**63
    a, b = read_skymap(path, nside=64), read_skymap(MAP_MULTIORDER, nside=64)
    np.testing.assert_allclose(a.prob, b.prob, rtol=1e-12, atol=1e-300)


def test_input_hash_is_of_the_bytes_given(tmp_path):
    packed = tmp_path / "moc.fits.gz"
    packed.write_bytes(gzip.compress(MAP_MULTIORDER.read_bytes()))
    for path in (MAP_MULTIORDER, packed):
        want = hashlib.sha256(path.read_bytes()).hexdigest()
        assert read_skymap(path, nside=16).sha256 == want == read_skymap(path.read_bytes(), nside=16).sha256


def _peak_bytes(path: Path, chunk: int) -> int:
    tracemalloc.start()
    try:
        read_skymap(path, nside=32, chunk=chunk)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_peak_memory_is_bounded_by_the_chunk_not_the_map(tmp_path):
    """Flat four-column RING maps, gzipped, read at NSIDE 32 in chunks of 2^13 pixels: NumPy's
    allocations (tracemalloc sees them) peak the same for NSIDE 128 and 256 (6 and 25 MB unpacked)."""
    small = _peak_bytes(_write_flat(tmp_path / "s.fits.gz", _rasterised(7), nest=False, packed=True), 1 << 13)
    big = _peak_bytes(_write_flat(tmp_path / "b.fits.gz", _rasterised(8), nest=False, packed=True), 1 << 13)
    assert big < 12 * 256**2 * 4 * 8 / 8 and big < 1.25 * small, (big, small)
    assert _peak_bytes(tmp_path / "b.fits.gz", 1 << 16) > 2 * big  # it is the chunk that sets it


# ---------------------------------------------------------------- hostile headers and bytes
def _fake_flat(nside: int, rows: int, per_row: int = 1024, data: bytes = b"", packed: bool = True,
               naxis1: int | None = None) -> bytes:
    """Headers declaring a flat map, then ``data``: a forged file (nothing checks it on the way out)."""
    primary = fits.PrimaryHDU().header.tostring().encode()
    h = fits.Header()
    h["XTENSION"], h["BITPIX"], h["NAXIS"] = "BINTABLE", 8, 2
    h["NAXIS1"], h["NAXIS2"] = naxis1 if naxis1 is not None else 8 * per_row, rows
    h["PCOUNT"], h["GCOUNT"], h["TFIELDS"] = 0, 1, 1
    h["TTYPE1"], h["TFORM1"] = "PROB", f"{per_row}D"
    h["PIXTYPE"], h["ORDERING"], h["NSIDE"], h["INDXSCHM"] = "HEALPIX", "NESTED", nside, "IMPLICIT"
    raw = primary + h.tostring().encode() + data
    return gzip.compress(raw) if packed else raw


@pytest.mark.parametrize("forge, message", [
    (lambda: _fake_flat(2**20, 12 * 4**20 // 1024), "NSIDE 1048576 is finer"),
    (lambda: _fake_flat(8192, 12 * 8192**2 // 1024), "more than a .*-byte gzip can unpack to"),
    (lambda: _fake_flat(1024, 12 * 1024**2 // 1024, packed=False, data=bytes(2880)), "truncated or forged"),
    (lambda: _fake_flat(1000, 12 * 1000**2 // 1024), "not a HEALPix map"),
    (lambda: _fake_flat(64, 48, naxis1=4096), "TFORMs add up"),
    (lambda: _fake_flat(64, 12 * 64**2 // 1024, data=np.random.default_rng(0).bytes(8192)), "truncated sky map"),
], ids=["nside-2^20", "beyond-deflate", "plain-truncated", "not-healpix", "tform-width", "gzip-truncated"])
def test_forged_headers_are_refused_before_reading_with_one_line(forge, message):
    with pytest.raises(SkyMapError, match=message) as err:
        read_skymap(forge(), nside=64)
    assert "\n" not in str(err.value)


def test_a_flat_gzip_grown_past_its_table_is_refused(tmp_path):
    import io

    path = _write_flat(tmp_path / "ok.fits", _rasterised(5))
    read_skymap(path, nside=32)
    z = zlib.compressobj(9, zlib.DEFLATED, 31)
    bomb = z.compress(path.read_bytes()) + z.compress(bytes(16 << 20)) + z.flush()
    with pytest.raises(SkyMapError, match="more bytes follow its declared table"):
        read_skymap(bomb, nside=32)
    buf = io.BytesIO()  # a second extension after the table is fine (never read)
    fits.HDUList([*fits.open(path), fits.ImageHDU(np.zeros(10))]).writeto(buf)
    assert read_skymap(gzip.compress(buf.getvalue()), nside=32).prob.sum() == pytest.approx(1)


def test_a_broken_gzip_stream_is_one_line():
    data = bytearray(gzip.compress(MAP_MULTIORDER.read_bytes()))
    data[len(data) // 2: len(data) // 2 + 64] = bytes(64)
    with pytest.raises(SkyMapError, match="gzip|truncated|UNIQ|sum") as err:
        read_skymap(bytes(data), nside=32)
    assert "\n" not in str(err.value)


def test_max_bytes_bounds_the_bytes_given_not_what_they_unpack_to(tmp_path):
    packed = gzip.compress(_write_flat(tmp_path / "f.fits", _rasterised(7)).read_bytes())  # 6.3 MB unpacked
    assert read_skymap(packed, nside=32, max_bytes=len(packed)).prob.sum() == pytest.approx(1)
    with pytest.raises(SkyMapError, match=f"{len(packed)} bytes, more than the {len(packed) - 1}-byte limit"):
        read_skymap(packed, nside=32, max_bytes=len(packed) - 1)


# ---------------------------------------------------------------- the one sniffer
def test_sniffer_tells_fits_gzip_fits_and_the_rest():
    raw = MAP_MULTIORDER.read_bytes()
    assert sniff_fits(raw) == "fits"
    assert sniff_fits(gzip.compress(raw)[:200]) == "gzip"
    assert sniff_fits(gzip.compress(b'{"superevent_id": "S1"}')) is None  # a gzip of something else
    assert sniff_fits(gzip.compress(gzip.compress(raw))) is None  # doubly packed
    assert sniff_fits(b"\x1f\x8bnot really gzip") == "gzip"  # broken: the reader says "broken gzip"
    assert sniff_fits(b"  SIMPLE  =") is None and sniff_fits(b"") is None and sniff_fits(b"{}") is None
