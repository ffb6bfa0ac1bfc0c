"""Read LVK sky maps (multi-order or flat HEALPix FITS, path or bytes), streaming.

The meaning is ligo.skymap's: what :func:`ligo.skymap.bayestar.rasterize`
makes of :func:`ligo.skymap.io.read_sky_map`'s table at one working NESTED
order.  Probability is integrated over each working pixel (exact, both
ways); a pixel coarser than the working order is shared among its children
with its distance layers; where pixels are merged, the distance layers are
combined through the conditional distance moments
(:func:`ligo.skymap.distance.parameters_to_moments`, probability-weighted
first and second moments, :func:`~ligo.skymap.distance.moments_to_parameters`;
a child without a finite distance makes the merged pixel ligo.skymap's
(inf, 1, 0)), so a working pixel's ansatz has the mean and variance of the
mixture it stands for.  Header metadata are read as ligo.skymap's
``FITS_META_MAPPING`` reads them (``DATE-OBS`` -> ``gps_time``, ``OBJECT``,
``DISTMEAN``; :func:`_metadata`, tested against it).

The route is ours (the arithmetic per working pixel in :mod:`.working_order`), because ligo.skymap's costs the map's
unpacked size: ``read_sky_map`` reads the whole table (astropy), and a
public O3 LALInference map (flat NSIDE 1024, four columns, 1.5 MB gzip)
unpacks to 384 MiB and cost 2.0 GB of RSS and 11.7 s before a greedy plan.
Here the rows stream through (:mod:`.fitstable`: astropy parses the
headers, NumPy reads a chunk of rows at a time from the plain or gzip
stream) and are accumulated at the working order as they come, vectorised
per chunk: RING rows get their NESTED index from :func:`healpy.ring2nest`;
finer pixels add their probability and probability-weighted moments to
their ancestor (``np.bincount``), coarser ones are spread to their
children.  Peak memory is one chunk (``chunk`` pixels) plus the working
arrays, whatever the map's NSIDE (up to 8192) or unpacked size.  Two
savings of the previous reader are kept in this form: only merged pixels
go through ``moments_to_parameters`` (rasterize 2.5.4 converts every output
pixel there and back: 5.1 s per notice map at NSIDE 256 against 0.08 s),
and a merged pixel whose children all carry the same (DISTMU, DISTSIGMA)
keeps them (a rasterised multi-order map's equal siblings: their mixture is
themselves) instead of being solved again.
``tests/scheduler/test_skymap.py`` and ``test_skymap_stream.py`` check the
result against ``rasterize(read_sky_map(..., moc=True))`` in moment space.

Hostile input is refused by what the header declares before any data is
read: a binary table whose row width its TFORMs give, a flat map of
12 NSIDE^2 pixels with NSIDE a power of two <= 8192, a multi-order map of
at most 2^22 rows of valid NUNIQ indices (order 0-29, no two covering the
same sky), a table that fits in the bytes given; reading stops at the
declared size, and bytes beyond it (a gzip grown past its table) are
refused.  Probabilities must be finite, non-negative and sum to 1.  Every
refusal is one :class:`~mushrooms.scheduler_core.errors.SkyMapError` line.
"""

from __future__ import annotations

import hashlib
import io
import logging
import math
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from astropy.time import Time

from ..errors import SkyMapError
from .distance_layers import usable_distance_layers
from .fitstable import BinaryTable, open_table
from .working_order import DIST_COLUMNS, WorkingOrder

__all__ = ["SkyMap", "read_skymap", "check_uniq", "DEFAULT_CHUNK", "MAX_NSIDE", "MAX_MOC_ROWS"]

log = logging.getLogger(__name__)

#: How far from 1 the total probability of an input map may be.
PROB_SUM_TOLERANCE = 0.02

#: Pixels (flat map) or rows (multi-order map) read per chunk: the reader's
#: peak memory beyond its working arrays is about 250 bytes x this (64 MiB).
DEFAULT_CHUNK = 1 << 18

#: Finest flat map read (HEALPix NSIDE; 2^13: 805 M pixels).
MAX_NSIDE = 8192

#: Most rows of a multi-order map (its NUNIQ check holds them: ~40 B a row).
#: LVK's BAYESTAR maps have 10-50 thousand, ligo-skymap-from-samples' up to
#: a few hundred thousand.
MAX_MOC_ROWS = 1 << 22

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


def _check_values(values: np.ndarray, name: str) -> None:
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise SkyMapError(f"{name}: probabilities must be finite and non-negative")


#: ``OBJECT`` values of LIGO_LW row ids (``"table:column:N"``), read as N (ligo.skymap's ``ilwd_to_int``).
_ILWD = re.compile(r"\s*\w+:\w+:(\d+)\s*")


def _object_id(value: Any) -> int | str:
    """``OBJECT`` as ligo.skymap's ``normalize_objid`` reads it: an integer, a row id's number, or the text."""
    try:
        return int(value)
    except ValueError:
        match = _ILWD.fullmatch(value)
        return int(match[1]) if match else str(value)


def _metadata(header: Any) -> dict[str, Any]:
    """The table header's metadata the plan uses, as ligo.skymap's ``read_sky_map`` names them.

    ``DATE-OBS`` -> ``gps_time`` (UTC ISO 8601 to GPS seconds), ``OBJECT``
    -> ``objid``, ``DISTMEAN`` -> ``distmean``: the rows of
    ``ligo.skymap.io.fits.FITS_META_MAPPING`` the plan reads, done here
    because importing that module loads all of ``ligo.skymap.io`` (GraceDB's
    client and LIGO_LW tables, 0.2 s of ``mushrooms plan``).
    ``MJD-OBS`` is not read (ligo.skymap does not read it either).
    """
    meta: dict[str, Any] = {}
    if "OBJECT" in header:
        meta["objid"] = _object_id(header["OBJECT"])
    if "DATE-OBS" in header:
        meta["gps_time"] = Time(header["DATE-OBS"], scale="utc").gps
    if "DISTMEAN" in header:
        meta["distmean"] = header["DISTMEAN"]
    return meta


def _open(source: str | Path | bytes) -> tuple[Any, str, int, str | None]:
    """File object, name, size and (for bytes) SHA-256 of a sky-map source."""
    if isinstance(source, (bytes, bytearray, memoryview)):
        data = bytes(source)
        if not data:
            raise SkyMapError("sky map is empty: <bytes>")
        return io.BytesIO(data), "<bytes>", len(data), hashlib.sha256(data).hexdigest()
    path = Path(source)
    if not path.exists():
        raise SkyMapError(f"sky map not found: {path}")
    if path.is_dir():
        raise SkyMapError(f"sky map is a directory, not a FITS file: {path}")
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise SkyMapError(f"cannot read sky map {path}: {exc.strerror or exc}") from None
    size = path.stat().st_size
    if size == 0:
        fh.close()
        raise SkyMapError(f"sky map is empty: {path}")
    return fh, str(path), size, None


def read_skymap(source: str | Path | bytes, nside: int = 256, max_bytes: int | None = None,
                chunk: int = DEFAULT_CHUNK) -> SkyMap:
    """Read a sky map and bring it to a working NESTED resolution, streaming.

    Parameters
    ----------
    source : str, pathlib.Path or bytes
        Path of a FITS file (``.fits``, ``.fits.gz``, multi-order or flat
        NSIDE <= 8192, NESTED or RING, with or without distance layers) or
        the file's bytes (e.g. a decoded notice payload).
    nside : int
        Working resolution (power of 2).
    max_bytes : int, optional
        Largest input (bytes as given: packed, for a gzip) accepted, e.g.
        ``[policy] max_skymap_bytes`` for what a notice or trigger may
        carry.  Default: no bound (a user's file).  What the map may unpack
        to is bounded by its own header (see the module docstring).
    chunk : int
        Pixels (flat map) or rows (multi-order map) read at a time; peak
        memory is about 250 bytes x ``chunk`` beyond the working arrays.

    Returns
    -------
    SkyMap

    Raises
    ------
    SkyMapError
        One line saying why: missing, empty, truncated or non-FITS file,
        broken gzip, a header declaring what HEALPix or the bytes cannot
        hold, bytes beyond the declared table, invalid NUNIQ indices, no
        probability column, probabilities negative, not finite, or not
        summing to 1 within 2 %.

    Examples
    --------
    The packaged multi-order BAYESTAR map, at a small working resolution:

    >>> from importlib.resources import files
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> skymap = read_skymap(path, nside=64)
    >>> skymap.nside, skymap.prob.size, skymap.object_id
    (64, 49152, 'MS181101ab')
    >>> round(float(skymap.prob.sum()), 6)
    1.0
    >>> skymap.event_time.isot
    '2018-11-01T22:22:46.654'
    >>> round(skymap.distmean, 1)  # Mpc
    39.8
    """
    if nside < 1 or nside & (nside - 1):
        raise SkyMapError(f"nside must be a power of 2, got {nside}")
    fh, name, size, sha = _open(source)
    try:
        if max_bytes is not None and size > max_bytes:
            raise SkyMapError(f"sky map {name} is {size} bytes, more than the {max_bytes}-byte limit")
        with warnings.catch_warnings():
            # an odd file is reported below as one SkyMapError line
            warnings.simplefilter("ignore")
            table = open_table(fh, name, size, hashed=sha is None)
            prob, layers, meta = _read_healpix(table, name, int(nside).bit_length() - 1, chunk)
            digest = table.finish()
    except SkyMapError:
        raise
    except Exception as exc:  # astropy/ligo/healpy raise many types for broken files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SkyMapError(f"unreadable FITS sky map {name}: {msg}") from None
    finally:
        fh.close()
    return _finish(prob, layers, meta, nside, sha or digest, name)


def _read_healpix(table: BinaryTable, name: str, order: int, chunk: int
                  ) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, Any]]:
    """Check a HEALPix table's declaration, then stream its rows into the working order."""
    header = table.header
    names = set(table.names)
    coordsys = str(header.get("COORDSYS", "C")).strip().upper()
    if coordsys and not coordsys.startswith("C"):
        raise SkyMapError(f"sky map {name} is in coordinates {coordsys!r}, not equatorial (COORDSYS = 'C')")
    ordering = str(header.get("ORDERING", "")).strip().upper()
    with_distance = set(DIST_COLUMNS) <= names
    working = WorkingOrder(order, with_distance)
    if "UNIQ" in names or ordering == "NUNIQ":
        _stream_multiorder(table, name, ordering, chunk, working)
    else:
        _stream_flat(table, name, ordering, chunk, working)
    prob, layers = working.result()
    # NaN, infinite or non-positive layers wherever the probability is: treated as absent, said once
    return prob, usable_distance_layers(prob, layers, name), _metadata(header)


def _need_columns(table: BinaryTable, name: str, columns: list[str]) -> None:
    missing = [c for c in columns if c not in table.names]
    if missing:
        raise SkyMapError(f"{name} has no {missing[0]} column (columns: {', '.join(table.names) or 'none'})")


def _stream_multiorder(table: BinaryTable, name: str, ordering: str, chunk: int, working: WorkingOrder) -> None:
    from ligo.skymap.moc import uniq2nest

    if ordering not in ("NUNIQ", ""):
        raise SkyMapError(f"{name} has a UNIQ column but ORDERING = {ordering!r}, not NUNIQ")
    _need_columns(table, name, ["UNIQ", "PROBDENSITY"])
    used = ["UNIQ", "PROBDENSITY"] + (list(DIST_COLUMNS) if working.with_distance else [])
    if any(table.repeats[c] != 1 for c in used):
        raise SkyMapError(f"{name}: a multi-order map has one value per row in each column")
    if table.rows > MAX_MOC_ROWS:
        raise SkyMapError(f"{name}: a multi-order map of {table.rows} rows, more than {MAX_MOC_ROWS}: refused")
    table.check_room()
    seen = []
    for rows in table.iter_rows(chunk):
        uniq = table.column(rows, "UNIQ", np.int64)
        bad = (uniq < 4) | (uniq >= 16 * 4**MAX_ORDER)
        if np.any(bad):
            raise SkyMapError(f"{name}: UNIQ value {int(uniq[np.argmax(bad)])} is not a HEALPix NUNIQ index "
                              f"(order 0-{MAX_ORDER})")
        seen.append(uniq)
        density = table.column(rows, "PROBDENSITY")
        _check_values(density, name)
        src_order, ipix = uniq2nest(uniq)
        src_order = src_order.astype(np.int64)
        prob = density * (math.pi / 3) / (np.int64(1) << (2 * src_order))  # x pixel area 4 pi / (12 4^order)
        layers = [table.column(rows, c) for c in DIST_COLUMNS] if working.with_distance else None
        working.add(src_order, ipix, prob, layers)
    try:
        check_uniq(np.concatenate(seen))
    except SkyMapError as exc:
        raise SkyMapError(f"{name}: {exc}") from None


def _stream_flat(table: BinaryTable, name: str, ordering: str, chunk: int, working: WorkingOrder) -> None:
    from .healpix import hp

    if not ordering:
        # healpy's read_map assumes whatever order its caller asks for; a wrong guess plans a scrambled sky
        raise SkyMapError(f"{name}: flat HEALPix map without ORDERING = 'RING' or 'NESTED' in its header: "
                          "the pixel order is unknown; set ORDERING and retry")
    if ordering not in ("RING", "NESTED"):
        raise SkyMapError(f"{name}: ORDERING = {ordering!r}; a HEALPix map is RING, NESTED or NUNIQ")
    if str(table.header.get("INDXSCHM", "IMPLICIT")).strip().upper() != "IMPLICIT":
        raise SkyMapError(f"{name}: an explicitly indexed (partial-sky) map is not supported")
    column = "PROBABILITY" if "PROBABILITY" in table.names and "PROB" not in table.names else "PROB"  # Fermi's name
    _need_columns(table, name, [column])
    used = [column] + (list(DIST_COLUMNS) if working.with_distance else [])
    per_row = {table.repeats[c] for c in used}
    if len(per_row) != 1:
        raise SkyMapError(f"{name}: its columns hold different numbers of pixels per row")
    per_row_n = per_row.pop()
    npix = table.rows * per_row_n
    src_order = ((npix // 12).bit_length() - 1) // 2
    if npix % 12 or 12 * 4**src_order != npix:
        raise SkyMapError(f"{name}: {npix} pixels is not a HEALPix map (12 NSIDE^2)")
    nside_in = 1 << src_order
    declared = table.header.get("NSIDE", nside_in)
    for what in (declared, nside_in):
        if isinstance(what, int) and what > MAX_NSIDE:
            raise SkyMapError(f"{name}: NSIDE {what} is finer than HEALPix maps are read here "
                              f"(NSIDE <= {MAX_NSIDE}): refused")
    if declared != nside_in:
        raise SkyMapError(f"{name}: NSIDE = {declared!r} but the table holds {npix} pixels (NSIDE {nside_in})")
    table.check_room()
    done = 0
    for rows in table.iter_rows(max(chunk // per_row_n, 1)):
        prob = table.column(rows, column)
        _check_values(prob, name)
        ipix = np.arange(done, done + prob.size, dtype=np.int64)
        done += prob.size
        if ordering == "RING":
            ipix = hp.ring2nest(nside_in, ipix)
        layers = [table.column(rows, c) for c in DIST_COLUMNS] if working.with_distance else None
        working.add(src_order, ipix, prob, layers)


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
