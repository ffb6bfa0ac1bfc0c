"""Field grids: read from a list (ZTF's ``ZTF_Fields.txt``, gwemopt's ``.tess``) or built from the field of view.

The built grid (``docs/design/telescopes.md`` §3, I1-I2) tiles the sphere with
a w x h rectangle (deg, in the plane of :mod:`.footprint`):

* (I1) two polar caps, one field centred on each pole, covering
  ``|dec| >= 90 - c`` with ``sin c = (pi / 180) min(w, h) / 2`` (the circle
  inscribed in the rectangle); declination bands of equal height ``H <= h (1 - f)``
  tile ``|dec| <= 90 - c (1 - f)``, overlapping the caps;
* (I2) band k (centre ``d0``) holds ``n_k = ceil(180 / a_k)`` fields evenly
  in RA, every other band shifted by half a step, where ``a_k`` is the
  largest RA offset (deg) at which the band's whole height still lies in
  the rectangle shrunk to ``w (1 - f)`` across: the offsets grow with the
  RA offset and are largest at the band's equator-most declination (x)
  and pole-most one (y), so two closed forms bound ``a_k``::

      x:  cos(d_eq) sin(a) <= (pi / 180) w (1 - f) / 2
      y:  cos(d0) sin(d_pole) - sin(d0) cos(d_pole) cos(a) <= (pi / 180) h / 2

  (southern bands mirrored).  Every point of the sphere then lies inside
  some field's rectangle, neighbours in a band overlap by at least
  ``f w`` and bands by the margin the y bound leaves; a field's detectors
  cover its rectangle only where they have no gaps.

Field ids are consecutive from ``first_id``: the south cap, the bands from
south to north (RA increasing), the north cap.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .footprint import seen_by_pointing

__all__ = ["MAX_FIELDS", "read_field_list", "declination_band_grid", "points_seen"]

#: The most fields a grid may hold (WINTER's 1 deg grid has ~41 000; a 0.1 deg one would be millions).
MAX_FIELDS = 200_000


def read_field_list(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Field ids and centres from a whitespace table: id, RA, Dec (deg), then anything; ``%``/``#`` comments.

    Raises
    ------
    ValueError
        One line naming the first bad row by number (never its text), a
        repeated id, a centre off the sphere, or more than :data:`MAX_FIELDS` rows.
    """
    ids, ra, dec = [], [], []
    for n, line in enumerate(text.splitlines(), start=1):
        words = line.split()
        if not words or words[0].startswith(("%", "#")):
            continue
        if len(ids) >= MAX_FIELDS:
            raise ValueError(f"more than {MAX_FIELDS} fields")
        try:
            if len(words) < 3:
                raise ValueError
            fid, r, d = float(words[0]), float(words[1]), float(words[2])
        except ValueError:
            raise ValueError(f"line {n}: expected a field id, RA and Dec (deg)") from None
        if not (fid == int(fid) and 0 <= fid < 2**53 and 0 <= r <= 360 and -90 <= d <= 90):
            raise ValueError(f"line {n}: id must be a whole number >= 0, RA in [0, 360], Dec in [-90, 90] deg")
        ids.append(int(fid))
        ra.append(r % 360.0)
        dec.append(d)
    if not ids:
        raise ValueError("no fields")
    out = np.array(ids, np.int64), np.array(ra, float), np.array(dec, float)
    if np.unique(out[0]).size != out[0].size:
        raise ValueError("a field id is repeated")
    return out


def _band_half_step(d0: np.ndarray, lo: np.ndarray, hi: np.ndarray, sx: float, sy: float) -> np.ndarray:
    """(I2) Largest RA offset (rad) covering each band [lo, hi] (rad) from fields at d0 (rad)."""
    sign = np.where(d0 < 0, -1.0, 1.0)  # mirror the south onto the north
    c0, plo, phi = d0 * sign, np.minimum(lo * sign, hi * sign), np.maximum(lo * sign, hi * sign)
    d_eq = np.where((plo < 0) & (phi > 0), 0.0, np.where(np.abs(plo) < np.abs(phi), plo, phi))
    with np.errstate(divide="ignore", invalid="ignore"):
        ax = np.arcsin(np.clip(sx / np.cos(d_eq), 0.0, 1.0))
        r = (np.cos(c0) * np.sin(phi) - sy) / (np.sin(c0) * np.cos(phi))
    ay = np.where(np.sin(c0) * np.cos(phi) > 0, np.arccos(np.clip(r, -1.0, 1.0)), np.pi / 2)
    ay = np.where(r > 1.0, 0.0, ay)
    return np.minimum(np.minimum(ax, ay), np.pi / 2)


def declination_band_grid(width_deg: float, height_deg: float, overlap: float = 0.1,
                          first_id: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A field grid covering the whole sphere with a ``width_deg`` x ``height_deg`` rectangle (I1-I2).

    Parameters
    ----------
    width_deg, height_deg : float
        The tiling rectangle (deg; east-west and north-south), at most 60.
    overlap : float
        Least overlap of neighbouring fields in a band, a fraction of the
        width (and the bands' height margin), in [0, 0.5).
    first_id : int
        Id of the first field (the south polar cap).

    Returns
    -------
    ids, ra, dec : numpy.ndarray
        Field ids and centres (deg).

    Examples
    --------
    >>> ids, ra, dec = declination_band_grid(6.9, 6.9, 0.1)
    >>> len(ids), float(dec.min()), float(dec.max())
    (1138, -90.0, 90.0)
    """
    if not (0 < width_deg <= 60 and 0 < height_deg <= 60 and 0 <= overlap < 0.5):
        raise ValueError("width and height must be in (0, 60] deg and overlap in [0, 0.5)")
    sx = np.radians(width_deg * (1.0 - overlap) / 2.0)  # the rectangle's half-sizes, in direction cosines
    sy = np.radians(height_deg / 2.0)
    cap = np.degrees(np.arcsin(min(np.radians(width_deg), np.radians(height_deg)) / 2.0))  # (I1)
    edge = 90.0 - cap * (1.0 - overlap)
    if 41253.0 / (width_deg * height_deg * (1.0 - overlap) ** 2) > MAX_FIELDS:  # before any array: a tiny field
        raise ValueError(f"a {width_deg:g} x {height_deg:g} deg field would need more than {MAX_FIELDS} fields")
    n_bands = int(np.ceil(2.0 * edge / (height_deg * (1.0 - overlap))))
    bounds = np.radians(np.linspace(-edge, edge, n_bands + 1))
    lo, hi = bounds[:-1], bounds[1:]
    centre = 0.5 * (lo + hi)
    half = _band_half_step(centre, lo, hi, sx, sy)
    if np.any(half <= 0):
        raise ValueError("the rectangle is too small for its declination bands")  # pragma: no cover
    counts = np.ceil(np.pi / half - 1e-9).astype(np.int64)
    if int(counts.sum()) + 2 > MAX_FIELDS:
        raise ValueError(f"the grid would hold {int(counts.sum()) + 2} fields, more than {MAX_FIELDS}")
    band = np.repeat(np.arange(n_bands), counts)
    step = 360.0 / counts[band]
    j = np.arange(band.size) - np.repeat(np.cumsum(counts) - counts, counts)
    ra = ((j + 0.5 * (band % 2)) * step) % 360.0
    dec = np.degrees(centre[band])
    ra = np.concatenate([[0.0], ra, [0.0]])
    dec = np.concatenate([[-90.0], dec, [90.0]])
    return np.arange(first_id, first_id + ra.size, dtype=np.int64), ra, dec


def points_seen(ra_deg: ArrayLike, dec_deg: ArrayLike, grid_ra: ArrayLike, grid_dec: ArrayLike,
                polygons: tuple[np.ndarray, ...], k: int = 8) -> np.ndarray:
    """Which sky positions fall on a detector of one of their ``k`` nearest fields (vectorised).

    Parameters
    ----------
    ra_deg, dec_deg : array_like
        (m,) positions (deg).
    grid_ra, grid_dec : array_like
        (n,) field centres (deg).
    polygons : tuple of numpy.ndarray
        Detector outlines (:mod:`.footprint`'s plane).
    k : int
        Nearest fields tried per position.

    Returns
    -------
    numpy.ndarray of bool
        (m,) the position is seen.
    """
    from scipy.spatial import cKDTree

    def unit(r: ArrayLike, d: ArrayLike) -> np.ndarray:
        r, d = np.radians(np.asarray(r, float)), np.radians(np.asarray(d, float))
        return np.stack([np.cos(d) * np.cos(r), np.cos(d) * np.sin(r), np.sin(d)], axis=-1)

    gra, gdec = np.asarray(grid_ra, float), np.asarray(grid_dec, float)
    _, near = cKDTree(unit(gra, gdec)).query(unit(ra_deg, dec_deg), k=min(k, gra.size))
    near = near.reshape(len(np.atleast_1d(ra_deg)), -1)
    ra = np.asarray(ra_deg, float)[:, None]
    dec = np.asarray(dec_deg, float)[:, None]
    return seen_by_pointing(ra, dec, gra[near], gdec[near], polygons).any(axis=1)
