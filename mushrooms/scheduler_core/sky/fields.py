"""ZTF's fixed field grid and the camera's 16-CCD footprint on the sky.

Data shipped with the package (see ``data/SOURCES.md``):
``ZTF_Fields.txt`` (1778 fields; BSD-3-Clause, ZTF) and
``ztf_ccd_layout.tbl`` (16 CCD outlines; Apache-2.0, ztffields).

A sky position falls on a CCD when its offsets from the field centre, in the
plane of the sky used by the layout table (orthographic projection,
``x = -cos(dec) sin(ra - ra0)``, ``y = cos(dec0) sin(dec) - sin(dec0)
cos(dec) cos(ra - ra0)``, degrees), lie inside that CCD's quadrilateral.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ..cachedir import cache_dir
from .footprints import Footprints
from .healpix import hp

__all__ = [
    "FieldGrid",
    "load_ztf_fields",
    "ccd_corners",
    "field_footprints",
    "project",
    "deproject",
    "FOOTPRINT_RADIUS_DEG",
    "Camera",
    "telescope_grid",
]

log = logging.getLogger(__name__)

#: Radius (deg) of a circle around the boresight that holds the whole camera.
FOOTPRINT_RADIUS_DEG = 5.3
_CACHE_VERSION = 2


@dataclass(frozen=True, eq=False)
class FieldGrid:
    """ZTF field centres.

    Attributes
    ----------
    ids : numpy.ndarray
        Field IDs (1-999 primary grid, 1001-1999 secondary grid).
    ra, dec : numpy.ndarray
        Field centres (deg, J2000).
    """

    ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray

    def __len__(self) -> int:
        return int(self.ids.size)

    def select(self, mask: np.ndarray) -> "FieldGrid":
        """Fields where ``mask`` is True."""
        return FieldGrid(self.ids[mask], self.ra[mask], self.dec[mask])

    def index_of(self, field_ids: np.ndarray) -> np.ndarray:
        """Row of each given field ID (-1 when unknown)."""
        order = np.argsort(self.ids)
        pos = np.searchsorted(self.ids, field_ids, sorter=order)
        pos = np.clip(pos, 0, self.ids.size - 1)
        rows = order[pos]
        return np.where(self.ids[rows] == field_ids, rows, -1)


@functools.lru_cache(maxsize=1)
def load_ztf_fields() -> FieldGrid:
    """All 1778 ZTF grid fields (primary and secondary) from package data.

    Examples
    --------
    >>> grid = load_ztf_fields()
    >>> len(grid), grid.ids.dtype.kind
    (1778, 'i')
    >>> bool((grid.dec >= -90).all() and (grid.ra < 360).all())  # degrees
    True
    """
    text = resources.files("mushrooms.scheduler_core").joinpath("data/ZTF_Fields.txt").read_text()
    rows = np.loadtxt(text.splitlines(), comments="%", usecols=(0, 1, 2))
    ids = rows[:, 0].astype(np.int64)
    return FieldGrid(ids=ids, ra=rows[:, 1].copy(), dec=rows[:, 2].copy())


def telescope_grid(telescope: object) -> FieldGrid:
    """The field grid of a :class:`~..instruments.TelescopeDescription` (``[grid]``: a file or built, I1-I2)."""
    centres = telescope.grid  # type: ignore[attr-defined]
    return FieldGrid(ids=centres.ids, ra=centres.ra, dec=centres.dec)


@functools.lru_cache(maxsize=1)
def ccd_corners() -> np.ndarray:
    """(16, 4, 2) CCD corner offsets (EW, NS) in deg, in polygon order."""
    text = resources.files("mushrooms.scheduler_core").joinpath("data/ztf_ccd_layout.tbl").read_text()
    rows = np.loadtxt(text.splitlines()[1:], delimiter=",")
    order = np.argsort(rows[:, 2], kind="stable")
    return rows[order, :2].reshape(16, 4, 2).copy()


def project(ra_deg: np.ndarray, dec_deg: np.ndarray, ra0_deg: float, dec0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Offsets (deg) of sky positions from a field centre, in the layout's plane.

    Parameters
    ----------
    ra_deg, dec_deg : numpy.ndarray
        Sky positions (deg).
    ra0_deg, dec0_deg : float
        Field centre (deg).

    Returns
    -------
    x, y : numpy.ndarray
        East-west and north-south offsets (deg), as in ``ztf_ccd_layout.tbl``.
    """
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    ra0, dec0 = np.radians(ra0_deg), np.radians(dec0_deg)
    x = -np.cos(dec) * np.sin(ra - ra0)
    y = np.cos(dec0) * np.sin(dec) - np.sin(dec0) * np.cos(dec) * np.cos(ra - ra0)
    return np.degrees(x), np.degrees(y)


def deproject(x_deg: np.ndarray, y_deg: np.ndarray, ra0_deg: float, dec0_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`project` (for points on the near hemisphere)."""
    x, y = np.radians(x_deg), np.radians(y_deg)
    ra0, dec0 = np.radians(ra0_deg), np.radians(dec0_deg)
    z = np.sqrt(np.clip(1.0 - x * x - y * y, 0.0, 1.0))
    centre = np.array([np.cos(dec0) * np.cos(ra0), np.cos(dec0) * np.sin(ra0), np.sin(dec0)])
    east = np.array([-np.sin(ra0), np.cos(ra0), 0.0])
    north = np.array([-np.sin(dec0) * np.cos(ra0), -np.sin(dec0) * np.sin(ra0), np.cos(dec0)])
    v = z[..., None] * centre + (-x)[..., None] * east + y[..., None] * north
    ra = np.degrees(np.arctan2(v[..., 1], v[..., 0])) % 360.0
    dec = np.degrees(np.arcsin(np.clip(v[..., 2], -1, 1)))
    return ra, dec


def _inside_any_ccd(x: np.ndarray, y: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Points (deg offsets) inside any of the convex CCD quadrilaterals.

    The CCDs are equal squares on a regular grid, so a point can only lie
    on the CCD whose centre is nearest; only that quadrilateral is tested.
    """
    centres = corners.mean(axis=1)  # (16, 2)
    d2 = (x[:, None] - centres[None, :, 0]) ** 2 + (y[:, None] - centres[None, :, 1]) ** 2
    quad = corners[np.argmin(d2, axis=1)]  # (m, 4, 2)
    a = quad
    b = np.roll(quad, -1, axis=1)
    cross = (b[..., 0] - a[..., 0]) * (y[:, None] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (x[:, None] - a[..., 0])
    orient = np.sign(np.sum(a[..., 0] * b[..., 1] - b[..., 0] * a[..., 1], axis=1))[:, None]
    return np.all(cross * orient >= 0, axis=1)


def _compute_footprints(grid: FieldGrid, nside: int, camera: "Camera | None" = None) -> Footprints:
    if camera is None:  # ZTF: the 16 equal CCDs, each point tested against its nearest CCD only
        corners = ccd_corners()
        radius = np.radians(FOOTPRINT_RADIUS_DEG)
        inside = lambda x, y: _inside_any_ccd(x, y, corners)  # noqa: E731
    else:  # any camera: every detector polygon, even-odd rule (I3), its edges included
        from ..instruments.footprint import inside_polygons

        radius = np.radians(camera.radius_deg)
        # a pixel centre on an edge two detectors share (a gapless mosaic's, often on a field's meridian) is on
        # both: each polygon grown about its centroid by 1e-9 of its size, as the checker's closed edges
        grown = tuple(p.mean(axis=0) + (p - p.mean(axis=0)) * (1.0 + 1e-9) for p in camera.polygons)
        inside = lambda x, y: inside_polygons(x, y, grown)  # noqa: E731
    rows: list[np.ndarray] = []
    vecs = hp.ang2vec(grid.ra, grid.dec, lonlat=True)
    for k in range(len(grid)):  # one vectorised step per field, never per pixel
        cand = hp.query_disc(nside, vecs[k], radius, inclusive=False, nest=True)
        pra, pdec = hp.pix2ang(nside, cand, nest=True, lonlat=True)
        x, y = project(pra, pdec, grid.ra[k], grid.dec[k])
        rows.append(np.sort(cand[inside(x, y)]).astype(np.int64))
    lengths = np.fromiter((r.size for r in rows), dtype=np.int64, count=len(rows))
    indptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    indices = np.concatenate(rows) if rows else np.zeros(0, np.int64)
    return Footprints(nside=nside, field_ids=grid.ids.copy(), indptr=indptr, indices=indices)


@dataclass(frozen=True, eq=False)
class Camera:
    """A camera's detectors about the pointing (deg, the layout's plane) for :func:`field_footprints`.

    Attributes
    ----------
    polygons : tuple of numpy.ndarray
        The detectors that make a field covered, (k, 2) corners each
        (:func:`~..instruments.active.covering_polygons`).
    radius_deg : float
        A circle about the pointing holding every detector (deg).
    """

    polygons: tuple[np.ndarray, ...]
    radius_deg: float


def _grid_key(grid: FieldGrid, nside: int, camera: Camera | None = None) -> str:
    h = hashlib.sha256()
    shape = (ccd_corners(),) if camera is None else camera.polygons
    for arr in (grid.ids, grid.ra, grid.dec, *shape):
        h.update(np.ascontiguousarray(arr).tobytes())
    radius = FOOTPRINT_RADIUS_DEG if camera is None else f"{camera.radius_deg!r}-{len(camera.polygons)}-closed-polygons"
    h.update(f"{nside}-{_CACHE_VERSION}-{radius}".encode())
    return h.hexdigest()[:16]


_memory_cache: dict[str, Footprints] = {}


def field_footprints(grid: FieldGrid | None = None, nside: int = 256, camera: Camera | None = None) -> Footprints:
    """Pixels (NESTED) whose centres fall on a CCD of each field.

    Computed once per grid and resolution, then kept in memory and in a
    disk cache (``$MUSHROOMS_CACHE_DIR``, systemd's ``$CACHE_DIRECTORY`` or
    ``~/.cache/mushrooms``); a cache that cannot be written is skipped.

    Parameters
    ----------
    grid : FieldGrid, optional
        Fields (default: the whole ZTF grid).
    nside : int
        HEALPix resolution.
    camera : Camera, optional
        Another telescope's detectors (default: ZTF's 16 CCDs).

    Returns
    -------
    Footprints
        Rows in the order of ``grid.ids``.
    """
    grid = grid if grid is not None else load_ztf_fields()
    key = _grid_key(grid, nside, camera)
    if key in _memory_cache:
        return _memory_cache[key]
    path = cache_dir() / f"footprints-{key}.npz"
    fp = None
    if path.exists():
        try:
            with np.load(path) as z:
                fp = Footprints(int(z["nside"]), z["field_ids"], z["indptr"], z["indices"])
        except Exception as exc:  # a damaged cache is rebuilt
            log.warning("ignoring unreadable footprint cache %s: %s", path, exc)
    if fp is None:
        fp = _compute_footprints(grid, nside, camera)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
            np.savez(tmp, nside=nside, field_ids=fp.field_ids, indptr=fp.indptr, indices=fp.indices)
            os.replace(tmp, path)
        except OSError as exc:
            log.debug("footprint cache not written (%s)", exc)
    _memory_cache[key] = fp
    return fp
