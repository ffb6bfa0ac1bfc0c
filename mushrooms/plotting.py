"""A picture of a plan: planned fields outlined on the sky map, coloured by time."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .scheduler_core.fields import ccd_corners, deproject, load_ztf_fields
from .scheduler_core.plan import Plan
from .scheduler_core.skymap import SkyMap

__all__ = ["plot_plan"]


def _outline(ra0: float, dec0: float) -> tuple[np.ndarray, np.ndarray]:
    """The camera's outer outline (deg) around a field centre."""
    c = ccd_corners()
    xmin, xmax = c[..., 0].min(), c[..., 0].max()
    ymin, ymax = c[..., 1].min(), c[..., 1].max()
    n = 20
    xs = np.concatenate([np.linspace(xmin, xmax, n), np.full(n, xmax), np.linspace(xmax, xmin, n), np.full(n, xmin)])
    ys = np.concatenate([np.full(n, ymin), np.linspace(ymin, ymax, n), np.full(n, ymax), np.linspace(ymax, ymin, n)])
    ra, dec = deproject(xs, ys, ra0, dec0)
    # break the line where it crosses RA = 0h so it is not drawn across the sky
    jump = np.flatnonzero(np.abs(np.diff(ra)) > 180.0) + 1
    return np.insert(ra, jump, np.nan), np.insert(dec, jump, np.nan)


def plot_plan(plan: Plan, skymap: SkyMap, path: str | Path, dpi: int = 120) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ligo.skymap/reproject deprecation chatter
        _plot_plan(plan, skymap, path, dpi)


def _plot_plan(plan: Plan, skymap: SkyMap, path: str | Path, dpi: int) -> None:
    """Draw the sky map with the planned fields outlined and coloured by first visit.

    Two panels: the whole sky (Mollweide) and a zoom on the planned fields
    and the 90 % credible region.

    Parameters
    ----------
    plan : Plan
        The plan.
    skymap : SkyMap
        Its sky map.
    path : str or pathlib.Path
        PNG file to write.
    dpi : int
        Resolution.
    """
    import matplotlib

    matplotlib.use("Agg")
    import ligo.skymap.plot  # noqa: F401  (registers the astro projections)
    from matplotlib import pyplot as plt
    from matplotlib.colors import Normalize

    first_visit: dict[int, float] = {}
    for o in plan.observations:
        first_visit.setdefault(o.field_id, o.start)
    hours = np.array(list(first_visit.values())) / 3600.0
    norm = Normalize(vmin=0.0, vmax=max(float(hours.max()) if hours.size else 1.0, 1e-3))
    cmap = plt.get_cmap("viridis")
    grid = load_ztf_fields()

    fig = plt.figure(figsize=(12, 6))
    ax_sky = fig.add_axes([0.02, 0.16, 0.5, 0.76], projection="astro hours mollweide")
    # zoom centre: probability-weighted centre of the planned fields, else the map peak
    import healpy as hp

    peak = int(np.argmax(skymap.prob))
    ra_c, dec_c = hp.pix2ang(skymap.nside, peak, nest=True, lonlat=True)
    if first_visit:
        rows = grid.index_of(np.array(list(first_visit)))
        vec = hp.ang2vec(grid.ra[rows], grid.dec[rows], lonlat=True).mean(axis=0)
        ra_c, dec_c = hp.vec2ang(vec / np.linalg.norm(vec), lonlat=True)
        ra_c, dec_c = float(np.squeeze(ra_c)), float(np.squeeze(dec_c))
        seps = np.degrees(np.arccos(np.clip(hp.ang2vec(grid.ra[rows], grid.dec[rows], lonlat=True)
                                            @ hp.ang2vec(ra_c, dec_c, lonlat=True), -1, 1)))
        radius = float(min(max(seps.max() + 6.0, 10.0), 80.0))
    else:
        radius = 20.0
    from astropy import units as u
    from astropy.coordinates import SkyCoord

    ax_zoom = fig.add_axes([0.58, 0.2, 0.36, 0.7], projection="astro degrees zoom",
                           center=SkyCoord(ra_c * u.deg, dec_c * u.deg), radius=radius * u.deg)
    for ax in (ax_sky, ax_zoom):
        ax.imshow_hpx((skymap.prob, "ICRS"), nested=True, cmap="cylon")
        ax.grid(alpha=0.3)
        for fid, t in first_visit.items():
            k = grid.index_of(np.array([fid]))[0]
            ra, dec = _outline(grid.ra[k], grid.dec[k])
            ax.plot(ra, dec, transform=ax.get_transform("world"), color=cmap(norm(t / 3600.0)), lw=1.0)
    ax_zoom.coords[0].set_axislabel("RA")
    ax_zoom.coords[1].set_axislabel("Dec")
    m = plan.metrics
    title = plan.event.superevent_id or skymap.object_id or Path(skymap.source).name
    fig.text(0.5, 0.965, f"{title}: {m.n_fields} fields, {m.n_exposures} exposures, coverage {m.coverage:.3f} "
                 f"({m.solver}); start {plan.start.isot[:16]} UTC", ha="center", fontsize=12)
    cax = fig.add_axes([0.3, 0.1, 0.4, 0.025])
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, cax=cax, orientation="horizontal", label="first visit (hours after start)")
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
