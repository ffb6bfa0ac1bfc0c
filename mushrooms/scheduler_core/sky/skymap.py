"""Read LVK sky maps (multi-order or flat HEALPix FITS, path or bytes).

Reading and rasterisation are ligo.skymap's own:
:func:`ligo.skymap.io.read_sky_map` reads the file and
:func:`ligo.skymap.bayestar.rasterize` brings it to one working NESTED
resolution.  Probability is integrated over each working pixel (exact, both
ways); where pixels are merged, the distance layers are combined through the
conditional distance moments (:func:`ligo.skymap.distance.parameters_to_moments`
and :func:`~ligo.skymap.distance.moments_to_parameters`), so a working pixel's
ansatz has the mean and variance of the mixture it stands for.  A flat map
enters the same rasterisation as a multi-order table (ligo.skymap's
``derasterize``, or the table of its one order when few siblings are equal).

Two steps are ours, each measured better than the library route (issue 15,
``tests/scheduler/test_skymap.py`` checks both against ligo.skymap's own
result): pixels finer than the working order are merged first
(``_merge_finer_pixels``, with ligo.skymap's moment functions and its
(inf, 1, 0) convention), because ligo.skymap 2.5.4's ``rasterize`` converts
*every* output pixel to moments and back as soon as any pixel needs merging
(786 432 numerical solves at NSIDE 256: 5.1 s per notice map against 0.08 s);
and a flat map whose sibling pixels are mostly unequal goes in as the table
of its one order instead of through ``derasterize``, whose Python loop over
pixels took 38 s of CPU on a noisy NSIDE 512 map (1 s this way).

What this module adds besides is the guard on hostile input (a bounded gunzip, the
NUNIQ validity check, finite non-negative probabilities summing to 1) and
one-line errors.
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
from .distance_layers import with_usable_distances

__all__ = ["SkyMap", "read_skymap", "check_uniq"]

log = logging.getLogger(__name__)

#: How far from 1 the total probability of an input map may be.
PROB_SUM_TOLERANCE = 0.02

#: Largest unpacked FITS (bytes) a gzipped sky map may grow to: 256 MiB, above
#: the largest real map we know (201 MB, a flat NSIDE 2048 map; LVK's
#: multi-order notice maps unpack to 1-5 MB).  A gzip bomb stops here.
MAX_SKYMAP_BYTES = 256 * 1024 * 1024

#: Least fraction of a flat map's sibling quadruples with equal probability for
#: it to go through ligo.skymap's derasterize (a rasterised multi-order map:
#: fast); below it the flat map is rasterised as one order (bounded cost).
MERGEABLE_FRACTION = 0.9

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
        Distance-ansatz layers (Mpc, Mpc, Mpc^-2) per pixel, or None.  A
        pixel whose distance posterior the ansatz cannot represent holds
        ligo.skymap's (inf, 1, 0).
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
    import astropy_healpix as ah
    from ligo.skymap.bayestar import rasterize  # heavy import, keep it lazy

    ordering, columns = _table_layout(raw)
    if ordering not in ("RING", "NESTED", "NUNIQ") and "UNIQ" not in columns:
        # healpy's read_map assumes whatever order its caller asks for; a wrong guess plans a scrambled sky
        raise SkyMapError(f"{name}: flat HEALPix map without ORDERING = 'RING' or 'NESTED' in its header "
                          f"(got {ordering or 'none'}): the pixel order is unknown; set ORDERING and retry")
    order = int(ah.nside_to_level(nside))
    table = with_usable_distances(_multiorder_table(raw, name, ordering, columns), name)
    working = rasterize(_merge_finer_pixels(table, order), order=order)  # now only shares coarser pixels
    prob = np.asarray(working["PROB"], float)
    layers = {c: np.asarray(working[c], float) for c in DIST_COLUMNS if c in working.colnames}
    return prob, layers, table.meta


def _multiorder_table(raw: bytes, name: str, ordering: str, columns: list[str]):
    """The map as ligo.skymap's multi-order table: UNIQ, PROBDENSITY (sr^-1), distance layers.

    A multi-order file is read by :func:`ligo.skymap.io.read_sky_map` with
    ``moc=True``; its NUNIQ indices are checked first (:func:`check_uniq`).
    A flat file (NESTED or RING, any nside) is read by the same function
    (reordered to NESTED) and turned into a multi-order table as
    ``read_sky_map(moc=True)`` does, by :func:`ligo.skymap.bayestar.derasterize`
    (which merges equal sibling pixels: a few seconds for real NSIDE 512-2048
    maps, most of whose siblings are equal) -- unless few siblings are
    equal: its walk costs about 12 µs per output pixel (38 s of CPU for a
    noisy NSIDE 512 map), so such a map becomes the multi-order table of its
    one order instead (1 s), the same map for
    :func:`~ligo.skymap.bayestar.rasterize`.  Only the probability and the
    three distance layers (when all are present) are kept.
    """
    import astropy_healpix as ah
    from astropy.table import Table
    from ligo.skymap.bayestar import derasterize
    from ligo.skymap.io import read_sky_map
    from ligo.skymap.moc import nest2uniq

    if ordering == "NUNIQ":
        table = read_sky_map(io.BytesIO(raw), moc=True)
        if "PROBDENSITY" not in table.colnames:
            raise SkyMapError(f"{name} has no PROBDENSITY column")
        try:
            check_uniq(np.asarray(table["UNIQ"]))
        except SkyMapError as exc:
            raise SkyMapError(f"{name}: {exc}") from None
        keep = ["UNIQ", "PROBDENSITY"] + (list(DIST_COLUMNS) if set(DIST_COLUMNS) <= set(table.colnames) else [])
        table = table[keep]
        table["PROBDENSITY"] = np.asarray(table["PROBDENSITY"], float)
        _check_values(np.asarray(table["PROBDENSITY"]), name)
        return table
    if "PROB" not in columns:
        raise SkyMapError(f"{name} has no PROB column (columns: {', '.join(columns) or 'none'})")
    with_dist = set(DIST_COLUMNS) <= set(columns)
    arrays, meta = read_sky_map(io.BytesIO(raw), nest=True, distances=with_dist)
    names = ("PROB",) + DIST_COLUMNS if with_dist else ("PROB",)
    table = Table([np.asarray(a, float) for a in (arrays if with_dist else (arrays,))], names=names, meta=meta)
    flat = np.asarray(table["PROB"])
    _check_values(flat, name)
    table = with_usable_distances(table, name)  # before derasterize: all-NaN layers made it drop 93 % of the sky
    if flat.size > 12 and np.mean(np.all(flat.reshape(-1, 4) == flat[::4, None], axis=1)) >= MERGEABLE_FRACTION:
        return derasterize(table)
    order = int(ah.nside_to_level(ah.npix_to_nside(flat.size)))
    table.rename_column("PROB", "PROBDENSITY")
    table["PROBDENSITY"] *= flat.size / (4 * np.pi)
    table.add_column(nest2uniq(np.int8(order), np.arange(flat.size, dtype=np.int64)), name="UNIQ", index=0)
    return table


def _merge_finer_pixels(table, order: int):
    """Multi-order table with every pixel finer than ``order`` merged into its ancestor.

    What :func:`ligo.skymap.bayestar.rasterize` does when it downsamples,
    with the same functions: the merged pixel's density is the mean of its
    children's, its distance layers those of the children's mixture
    (:func:`ligo.skymap.distance.parameters_to_moments`, probability-weighted
    first and second moments, :func:`~ligo.skymap.distance.moments_to_parameters`;
    a child without a finite distance makes the merged one (inf, 1, 0)).
    Done here only for the merged pixels: ``rasterize`` converts every
    output pixel there and back (moments_to_parameters solves each
    numerically), 5 s for a notice's map at NSIDE 256 against 0.1 s here,
    and loses up to 2e-5 of the std of the pixels it only shares.
    """
    from astropy.table import Table, vstack
    from ligo.skymap.distance import moments_to_parameters, parameters_to_moments
    from ligo.skymap.moc import nest2uniq, uniq2nest

    src_order, ipix = uniq2nest(np.asarray(table["UNIQ"]))
    fine = src_order > order
    if not np.any(fine):
        return table
    shift = 2 * (src_order[fine].astype(np.int64) - order)
    parents, group = np.unique(ipix[fine] >> shift, return_inverse=True)
    weight = np.asarray(table["PROBDENSITY"], float)[fine] / (np.int64(1) << shift)  # density x child/parent area
    density = np.bincount(group, weight)
    merged = Table({"UNIQ": nest2uniq(np.int8(order), parents), "PROBDENSITY": density})
    if "DISTMU" in table.colnames:
        mu, sigma = (np.asarray(table[c], float)[fine] for c in ("DISTMU", "DISTSIGMA"))
        with np.errstate(invalid="ignore", divide="ignore"):
            mean, std, _ = parameters_to_moments(mu, sigma)
            bad = ~(np.isfinite(mu) & np.isfinite(sigma))
            mean[bad] = std[bad] = np.nan
            first = np.bincount(group, weight * mean) / density
            second = np.bincount(group, weight * (std**2 + mean**2)) / density
            layers = moments_to_parameters(first, np.sqrt(second - first**2))
        for column, values in zip(DIST_COLUMNS, layers):
            merged[column] = values
    coarse = Table({c: np.asarray(table[c])[~fine] for c in merged.colnames})
    return vstack([coarse, merged])


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
