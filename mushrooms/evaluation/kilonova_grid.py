"""Kilonovae drawn over ejecta mass and viewing angle from a published POSSIS grid (scoring only).

The planner optimises with one light curve per configuration
(:mod:`mushrooms.scheduler_core.source.kilonova`); the independent scoring
(:mod:`.independent_scoring`) draws every injection's kilonova instead from
the grid of Bulla (2019, MNRAS 489, 5037; the ``bns_m1_2comp`` grid of
``mbulla/kilonova_models``): total ejecta mass 0.01-0.10 Msun (10 values),
half-opening angle of the lanthanide-rich component 15-75 deg (5), temperature
at 1 d 3000-9000 K (4), 11 viewing angles equally spaced in cos(theta) from
the equator (0) to the pole (1), epochs 0.5-10 d every 0.5 d.  The package
ships ZTF g and r absolute magnitudes derived from the spectra
(``data/possis_bulla2019_ztf.csv.gz``, ``data/SOURCES.md``,
``benchmarks/science/possis_ztf_table.py``).

Per injection (seeded): a grid model uniformly over its 200 (mass, angle,
temperature) points, so the ejecta mass is uniform over the grid's ten
values; ``cos(theta)`` uniform in [0, 1] (an isotropic viewer; the models are
symmetric about the equator), the magnitude interpolated linearly in
``cos(theta)`` between the grid's angles and in time between its epochs.

Before the first epoch (0.5 d) the grid says nothing.  ``early="fireball"``
(default) lets the flux rise as ``t^2`` to the first epoch (a photosphere
expanding at constant speed and a temperature that does not rise:
``M(t) = M(t_1) + 5 log10(t_1 / t)``); ``early="dark"`` counts nothing before
it (the conservative reading).  After the last epoch the source is faded
(``+inf``); at ``t <= 0`` it does not exist.
"""

from __future__ import annotations

import csv
import functools
import gzip
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = ["KilonovaGrid", "KilonovaDraws", "load_kilonova_grid", "draw_kilonovae", "grid_absolute_mag",
           "EARLY_RULES", "GRID_FILE"]

#: The packaged table (ZTF g, r absolute AB magnitudes at 10 pc).
GRID_FILE = "possis_bulla2019_ztf.csv.gz"
#: What the source does before the grid's first epoch.
EARLY_RULES = ("fireball", "dark")


@dataclass(frozen=True, eq=False)
class KilonovaGrid:
    """A POSSIS grid as ZTF magnitudes.

    Attributes
    ----------
    params : numpy.ndarray
        (k, 3) ejecta mass (Msun), half-opening angle (deg), temperature at 1 d (K) of each model.
    cos_theta : numpy.ndarray
        (a,) viewing angles, increasing, equally spaced from 0 to 1.
    epochs_days : numpy.ndarray
        (t,) epochs (days after merger), equally spaced.
    mags : dict
        Band -> (k, a, t) absolute AB magnitudes (``inf``: no flux).
    """

    params: np.ndarray
    cos_theta: np.ndarray
    epochs_days: np.ndarray
    mags: dict[str, np.ndarray]

    @property
    def n_models(self) -> int:
        """Number of (mass, angle, temperature) models."""
        return int(self.params.shape[0])


@dataclass(frozen=True, eq=False)
class KilonovaDraws:
    """One kilonova per injection.

    Attributes
    ----------
    model : numpy.ndarray
        (n,) row of :attr:`KilonovaGrid.params`.
    cos_theta : numpy.ndarray
        (n,) cosine of the viewing angle from the pole axis, in [0, 1].
    """

    model: np.ndarray
    cos_theta: np.ndarray

    def __len__(self) -> int:
        return int(self.model.size)


def _read_table(path: Path) -> KilonovaGrid:
    """Parse the packaged CSV (one row per model, angle and band; one column per epoch)."""
    with gzip.open(path, "rt") as fh:
        rows = list(csv.reader(line for line in fh if not line.startswith("#")))
    header, body = rows[0], rows[1:]
    epochs = np.array([float(c[1:]) for c in header[5:]])
    keys = np.array([[float(r[0]), float(r[1]), float(r[2])] for r in body])
    cos = np.array([float(r[3]) for r in body])
    bands = np.array([r[4] for r in body])
    values = np.array([[float(x) for x in r[5:]] for r in body])
    params, model = np.unique(keys, axis=0, return_inverse=True)
    angles, angle = np.unique(cos, return_inverse=True)
    mags = {}
    for band in sorted(set(bands.tolist())):
        cube = np.full((params.shape[0], angles.size, epochs.size), np.inf)
        sel = bands == band
        cube[model.ravel()[sel], angle[sel]] = values[sel]
        mags[band] = cube
    return KilonovaGrid(params=params, cos_theta=angles, epochs_days=epochs, mags=mags)


@functools.lru_cache(maxsize=2)
def load_kilonova_grid(path: str | None = None) -> KilonovaGrid:
    """The packaged Bulla (2019) grid in ZTF g and r (or a table of the same form at ``path``)."""
    if path is None:
        with resources.as_file(resources.files("mushrooms.evaluation") / "data" / GRID_FILE) as p:
            return _read_table(Path(p))
    return _read_table(Path(path))


def draw_kilonovae(grid: KilonovaGrid, n: int, rng: np.random.Generator | int) -> KilonovaDraws:
    """``n`` kilonovae: a grid model uniformly, ``cos(theta)`` uniform in [0, 1] (isotropic viewers)."""
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    return KilonovaDraws(model=rng.integers(0, grid.n_models, size=n), cos_theta=rng.random(n))


def _bracket(x: np.ndarray, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower index and weight of the upper neighbour of ``x`` on an equally spaced ``grid`` (clipped)."""
    step = (grid[-1] - grid[0]) / (grid.size - 1)
    u = np.clip((x - grid[0]) / step, 0.0, grid.size - 1 - 1e-9)
    lo = np.floor(u).astype(np.int64)
    return lo, u - lo


def grid_absolute_mag(grid: KilonovaGrid, draws: KilonovaDraws, band: str, t_days: np.ndarray,
                      early: str = "fireball") -> np.ndarray:
    """Absolute magnitude of every drawn kilonova at every time.

    Parameters
    ----------
    grid : KilonovaGrid
        The models.
    draws : KilonovaDraws
        (n,) kilonovae.
    band : str
        ``g`` or ``r``.
    t_days : array_like
        (m,) times since the merger (days).
    early : str
        Before the first epoch: ``fireball`` (``t^2`` flux rise) or ``dark``.

    Returns
    -------
    numpy.ndarray
        (m, n) AB magnitudes; ``inf`` where the source is not there or not modelled.
    """
    if early not in EARLY_RULES:
        raise ValueError(f"early must be one of {', '.join(EARLY_RULES)}, got {early!r}")
    if band not in grid.mags:
        raise ValueError(f"the kilonova grid has no band {band!r} (bands: {', '.join(grid.mags)})")
    cube = grid.mags[band][draws.model]  # (n, a, t)
    t = np.asarray(t_days, float)
    t1, t_last = float(grid.epochs_days[0]), float(grid.epochs_days[-1])
    ia, wa = _bracket(draws.cos_theta, grid.cos_theta)
    it, wt = _bracket(np.clip(t, t1, t_last), grid.epochs_days)
    n = np.arange(len(draws))
    with np.errstate(invalid="ignore"):
        by_angle = (cube[n, ia] * (1.0 - wa)[:, None] + cube[n, ia + 1] * wa[:, None])  # (n, t)
        mag = by_angle[:, it] * (1.0 - wt) + by_angle[:, it + 1] * wt  # (n, m)
    mag = np.where(np.isnan(mag), np.inf, mag).T
    with np.errstate(divide="ignore"):
        rise = 5.0 * np.log10(t1 / np.where(t > 0, t, np.nan))
    before = (t > 0) & (t < t1)
    if early == "fireball":
        mag = np.where(before[:, None], mag + rise[:, None], mag)
    else:
        mag = np.where(before[:, None], np.inf, mag)
    return np.where(((t <= 0) | (t > t_last))[:, None], np.inf, mag)
