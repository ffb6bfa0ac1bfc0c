"""Read LVK sky maps (multi-order or flat HEALPix FITS, path or bytes).

The map is brought to one working NESTED resolution: probability is summed
into coarser pixels or shared equally among finer ones (exact for the
probability), distance layers are probability-weighted averages.
"""

from __future__ import annotations

import gzip
import hashlib
import io
import logging
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from astropy.time import Time

from ..errors import SkyMapError

__all__ = ["SkyMap", "read_skymap", "rasterize_moc"]

log = logging.getLogger(__name__)

#: How far from 1 the total probability of an input map may be.
PROB_SUM_TOLERANCE = 0.02

#: Largest unpacked FITS (bytes) a gzipped sky map may grow to: 256 MiB, above
#: the largest real map we know (201 MB, a flat NSIDE 2048 map; LVK's
#: multi-order notice maps unpack to 1-5 MB).  A gzip bomb stops here.
MAX_SKYMAP_BYTES = 256 * 1024 * 1024

#: HEALPix's deepest order (NUNIQ indices beyond it are invalid).
MAX_ORDER = 29


@dataclass(frozen=True, eq=False)
class SkyMap:
    """A sky map at the working resolution.

    Attributes
    ----------
    prob : numpy.ndarray
        Probability per pixel (NESTED, ``nside``), summing to 1.
    nside : int
        HEALPix resolution.
    event_time : astropy.time.Time or None
        Merger time (UTC) from the map's header.
    object_id : str or None
        The map's OBJECT (superevent or graceid).
    distmu, distsigma, distnorm : numpy.ndarray or None
        Distance-ansatz layers (Mpc, Mpc, Mpc^-2) per pixel, or None.
    distmean : float or None
        Posterior mean distance (Mpc) from the header.
    sha256 : str
        SHA-256 of the input bytes (what the plan id is keyed on).
    source : str
        Where the map came from (a path or ``<bytes>``).
    """

    prob: np.ndarray
    nside: int
    event_time: Time | None
    object_id: str | None
    distmu: np.ndarray | None
    distsigma: np.ndarray | None
    distnorm: np.ndarray | None
    distmean: float | None
    sha256: str
    source: str

    @property
    def has_distance(self) -> bool:
        """True when the distance layers are present."""
        return self.distmu is not None

    def credible_area(self, level: float = 0.9) -> float:
        """Area (deg^2) of the smallest region holding ``level`` probability."""
        p = np.sort(self.prob)[::-1]
        n = int(np.searchsorted(np.cumsum(p), level) + 1)
        return n * 41252.96124941928 / self.prob.size


def _uniq_to_order_ipix(uniq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    from ligo.skymap.moc import uniq2nest

    order, ipix = uniq2nest(np.asarray(uniq, dtype=np.int64))
    return order.astype(np.int64), ipix


def check_uniq(uniq: np.ndarray) -> None:
    """Refuse NUNIQ indices that do not describe a multi-order HEALPix map.

    Each index must decode (ligo.skymap's :func:`~ligo.skymap.moc.uniq2order`)
    to an order in 0..29, and no two pixels may cover the same sky (a
    duplicate, or a pixel and one of its ancestors).

    Raises
    ------
    SkyMapError
        Naming the first problem found.
    """
    from ligo.skymap.moc import uniq2nest

    uniq = np.asarray(uniq)
    if uniq.ndim != 1 or uniq.size == 0 or not np.issubdtype(uniq.dtype, np.integer):
        raise SkyMapError("UNIQ column must be a non-empty list of integers")
    order, ipix = uniq2nest(uniq.astype(np.int64))
    bad = (order < 0) | (order > MAX_ORDER)
    if np.any(bad):
        raise SkyMapError(f"UNIQ value {int(uniq[np.argmax(bad)])} is not a HEALPix NUNIQ index (order 0-{MAX_ORDER})")
    shift = 2 * (MAX_ORDER - order.astype(np.int64))
    first = ipix << shift  # the range of deepest-order pixels each pixel covers
    last = ((ipix + 1) << shift) - 1
    by_start = np.argsort(first, kind="stable")
    overlap = first[by_start][1:] <= last[by_start][:-1]
    if np.any(overlap):
        i = int(np.argmax(overlap))
        a, b = uniq[by_start[i]], uniq[by_start[i + 1]]
        raise SkyMapError(f"UNIQ values {int(a)} and {int(b)} cover the same sky (duplicate or nested pixels)")


def rasterize_moc(uniq: np.ndarray, probdensity: np.ndarray, order: int,
                  layers: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Multi-order (NUNIQ) map to a NESTED map of the given order, vectorised.

    Parameters
    ----------
    uniq : numpy.ndarray
        NUNIQ pixel indices.
    probdensity : numpy.ndarray
        Probability per steradian of each multi-order pixel.
    order : int
        Target HEALPix order (nside = 2**order).
    layers : dict, optional
        Extra per-pixel columns to carry as probability-weighted means.

    Returns
    -------
    prob : numpy.ndarray
        Probability per target pixel.
    means : dict
        Probability-weighted mean of each layer per target pixel (NaN where
        the probability is zero).
    """
    src_order, ipix = _uniq_to_order_ipix(uniq)
    npix = 12 * 4**order
    area = 4 * np.pi / (12 * 4.0**src_order)
    p = np.asarray(probdensity, float) * area
    prob = np.zeros(npix)
    layers = {k: np.asarray(v, float) for k, v in (layers or {}).items()}
    sums = {k: np.zeros(npix) for k in layers}
    weights = {k: np.zeros(npix) for k in layers}
    finite = {k: np.isfinite(v) for k, v in layers.items()}
    clean = {k: np.where(finite[k], v, 0.0) for k, v in layers.items()}

    coarse = src_order >= order  # several source pixels per target pixel
    tgt = ipix[coarse] >> (2 * (src_order[coarse] - order))
    prob += np.bincount(tgt, p[coarse], minlength=npix)
    for k in layers:
        w = p[coarse] * finite[k][coarse]
        sums[k] += np.bincount(tgt, w * clean[k][coarse], minlength=npix)
        weights[k] += np.bincount(tgt, w, minlength=npix)

    fine = ~coarse  # one source pixel spreads over 4**(order - src_order) targets
    if np.any(fine):
        shift = 2 * (order - src_order[fine])
        counts = np.int64(1) << shift
        first = ipix[fine] << shift
        reps = np.repeat(np.arange(fine.sum()), counts)
        offsets = np.arange(reps.size) - np.repeat(np.cumsum(counts) - counts, counts)
        tgt_f = np.repeat(first, counts) + offsets
        share = np.repeat(p[fine] / counts, counts)
        prob += np.bincount(tgt_f, share, minlength=npix)
        for k in layers:
            w = share * np.repeat(finite[k][fine], counts)
            sums[k] += np.bincount(tgt_f, w * np.repeat(clean[k][fine], counts), minlength=npix)
            weights[k] += np.bincount(tgt_f, w, minlength=npix)

    with np.errstate(invalid="ignore", divide="ignore"):
        means = {k: np.where(weights[k] > 0, sums[k] / weights[k], np.nan) for k in layers}
    return prob, means


def regrade_nested(prob: np.ndarray, nside: int,
                   layers: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Flat NESTED map (probability per pixel) to another resolution.

    Parameters
    ----------
    prob : numpy.ndarray
        Probability per pixel, NESTED.
    nside : int
        Target resolution.
    layers : dict, optional
        Per-pixel columns carried as probability-weighted means.

    Returns
    -------
    prob : numpy.ndarray
    means : dict
    """
    prob = np.asarray(prob, float)
    npix_out = 12 * nside * nside
    layers = {k: np.asarray(v, float) for k, v in (layers or {}).items()}
    if prob.size >= npix_out:
        k = prob.size // npix_out
        out = prob.reshape(npix_out, k).sum(axis=1)
        means = {}
        for name, v in layers.items():
            finite = np.isfinite(v)
            w = prob * finite
            num = (w * np.where(finite, v, 0.0)).reshape(npix_out, k).sum(axis=1)
            den = w.reshape(npix_out, k).sum(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                means[name] = np.where(den > 0, num / den, np.nan)
        return out, means
    k = npix_out // prob.size
    return np.repeat(prob / k, k), {name: np.repeat(v, k) for name, v in layers.items()}


DIST_COLUMNS = ("DISTMU", "DISTSIGMA", "DISTNORM")


def _table_layout(raw: bytes) -> tuple[str, list[str]]:
    """ORDERING keyword and column names of the first table HDU."""
    from astropy.io import fits

    with fits.open(io.BytesIO(raw), memmap=False) as hdus:
        if len(hdus) < 2 or not hasattr(hdus[1], "columns"):
            raise SkyMapError("FITS file has no HEALPix table extension")
        header = hdus[1].header
        return str(header.get("ORDERING", "")).upper(), [c.upper() for c in hdus[1].columns.names]


def _check_values(values: np.ndarray, name: str) -> None:
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise SkyMapError(f"{name}: probabilities must be finite and non-negative")


def _gunzip(data: bytes, name: str, max_bytes: int) -> bytes:
    """Unpack a gzip stream, refusing to grow beyond ``max_bytes``."""
    out = bytearray()
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as fh:
            while chunk := fh.read(1 << 20):
                out += chunk
                if len(out) > max_bytes:
                    raise SkyMapError(f"gzipped sky map {name} unpacks to more than {_mib(max_bytes)} "
                                      f"(from {len(data)} bytes): refused")
                if len(out) >= 2880 and not out.startswith(b"SIMPLE  ="):
                    break  # not FITS: said below without unpacking the rest
    except (OSError, EOFError, zlib.error) as exc:  # BadGzipFile is an OSError
        raise SkyMapError(f"broken gzip in sky map {name}: {exc}") from None
    return bytes(out)


def _mib(n: int) -> str:
    return f"{n / 2**20:g} MiB"


def _read_bytes(source: str | Path | bytes) -> tuple[bytes, str]:
    if isinstance(source, (bytes, bytearray, memoryview)):
        return bytes(source), "<bytes>"
    path = Path(source)
    if not path.exists():
        raise SkyMapError(f"sky map not found: {path}")
    if path.is_dir():
        raise SkyMapError(f"sky map is a directory, not a FITS file: {path}")
    try:
        return path.read_bytes(), str(path)
    except OSError as exc:
        raise SkyMapError(f"cannot read sky map {path}: {exc.strerror or exc}") from None


def read_skymap(source: str | Path | bytes, nside: int = 256, max_bytes: int = MAX_SKYMAP_BYTES) -> SkyMap:
    """Read a sky map and bring it to a working NESTED resolution.

    Parameters
    ----------
    source : str, pathlib.Path or bytes
        Path of a FITS file (``.fits``, ``.fits.gz``, multi-order or flat,
        NESTED or RING) or the file's bytes (e.g. a decoded notice payload).
    nside : int
        Working resolution (power of 2).
    max_bytes : int
        Largest size (bytes) a gzipped map may unpack to; the stream is
        unpacked chunk by chunk and refused as soon as it grows beyond
        this (a decompression bomb costs at most ``max_bytes`` of memory).

    Returns
    -------
    SkyMap

    Raises
    ------
    SkyMapError
        One line saying why: missing, empty, truncated or non-FITS file,
        broken gzip or one unpacking beyond ``max_bytes``, invalid NUNIQ
        indices, no probability column, probabilities negative, not finite,
        or not summing to 1 within 2 %.
    """
    if nside < 1 or nside & (nside - 1):
        raise SkyMapError(f"nside must be a power of 2, got {nside}")
    data, name = _read_bytes(source)
    if not data:
        raise SkyMapError(f"sky map is empty: {name}")
    sha = hashlib.sha256(data).hexdigest()
    raw = _gunzip(data, name, max_bytes) if data[:2] == b"\x1f\x8b" else data
    if not raw.startswith(b"SIMPLE  ="):
        raise SkyMapError(f"not a FITS file: {name}")
    try:
        with warnings.catch_warnings():
            # a truncated or odd file is reported below as one SkyMapError line
            warnings.simplefilter("ignore")
            prob, means, meta = _read_table(raw, name, nside)
    except SkyMapError:
        raise
    except Exception as exc:  # astropy/ligo raise many types for broken files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SkyMapError(f"unreadable FITS sky map {name}: {msg}") from None
    return _finish(prob, means, meta, nside, sha, name)


def _read_table(raw: bytes, name: str, nside: int) -> tuple[np.ndarray, dict[str, np.ndarray], dict]:
    """Probability, distance layers and header of a FITS sky map at ``nside``."""
    from ligo.skymap.io import read_sky_map  # heavy import, keep it lazy

    ordering, columns = _table_layout(raw)
    if ordering == "NUNIQ":
        table = read_sky_map(io.BytesIO(raw), moc=True)
        meta = table.meta
        if "PROBDENSITY" not in table.colnames:
            raise SkyMapError(f"{name} has no PROBDENSITY column")
        try:
            check_uniq(np.asarray(table["UNIQ"]))
        except SkyMapError as exc:
            raise SkyMapError(f"{name}: {exc}") from None
        density = np.asarray(table["PROBDENSITY"], float)
        _check_values(density, name)
        layers = {c: np.asarray(table[c], float) for c in DIST_COLUMNS} if set(DIST_COLUMNS) <= set(table.colnames) else {}
        prob, means = rasterize_moc(np.asarray(table["UNIQ"]), density, int(np.log2(nside)), layers)
    else:
        if "PROB" not in columns:
            raise SkyMapError(f"{name} has no PROB column (columns: {', '.join(columns) or 'none'})")
        with_dist = set(DIST_COLUMNS) <= set(columns)
        arrays, meta = read_sky_map(io.BytesIO(raw), nest=True, distances=with_dist)
        if with_dist:
            flat, layers = arrays[0], dict(zip(DIST_COLUMNS, arrays[1:]))
        else:
            flat, layers = arrays, {}
        flat = np.asarray(flat, float)
        _check_values(flat, name)
        prob, means = regrade_nested(flat, nside, layers)
    return prob, means, meta


def _finish(prob: np.ndarray, means: dict[str, np.ndarray], meta: dict, nside: int, sha: str, name: str) -> SkyMap:
    total = float(prob.sum())
    if not abs(total - 1.0) <= PROB_SUM_TOLERANCE:
        raise SkyMapError(f"{name}: probabilities sum to {total:.4g}, not 1 (±{PROB_SUM_TOLERANCE:g})")
    prob = prob / total

    event_time = None
    if meta.get("gps_time") is not None:
        event_time = Time(float(meta["gps_time"]), format="gps").utc
    obj = meta.get("objid")
    distmean = meta.get("distmean")
    return SkyMap(
        prob=prob,
        nside=nside,
        event_time=event_time,
        object_id=None if obj is None else str(obj),
        distmu=means.get("DISTMU"),
        distsigma=means.get("DISTSIGMA"),
        distnorm=means.get("DISTNORM"),
        distmean=None if distmean is None else float(distmean),
        sha256=sha,
        source=name,
    )
