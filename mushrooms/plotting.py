"""A picture of a plan: the sky map, the planned fields and path, their airmass over the night, the timeline.

Four panels; the two sky panels share one probability colour scale: the
whole sky (Mollweide, with the Sun and the Moon at the horizon start) and a
zoom on the probability the plan covers (on the 90 % credible region without
a plan), both with the 50 % and 90 % credible contours and the fields
outlined (ids written in the zoom), the fields already executed (a re-plan)
filled grey, the observing path drawn visit by visit in the colour of its
filter with a white edge (readable on the map's colours); the airmass of
each planned field over the night with night and twilight shaded and the
Moon (:mod:`.plot_airmass`); and a timeline of the horizon (day, twilight,
night, each exposure by filter).  The title gives the total coverage (a
re-plan: the executed part included).  Without a sky map (the outbox's
summary page) only the airmass panel and the timeline are drawn.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from .plot_airmass import FILTER_COLOURS, SKY_SHADES
from .scheduler_core.sky.fields import ccd_corners, deproject, load_ztf_fields
from .scheduler_core.plan.document import Plan
from .scheduler_core.sky.skymap import SkyMap

__all__ = ["plot_plan", "plan_picture_png", "FILTER_COLOURS", "plot_title", "zoom_holding_fields"]

#: Executed fields (a re-plan), filled on the sky panels.
EXECUTED_COLOUR = "#9a9a9a"



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


def filters_of(plan: Plan) -> list[str]:
    """The plan's filters in order of first use (the configured ones for an empty plan)."""
    return list(dict.fromkeys(o.filter for o in plan.observations)) or \
        list((plan.config or {}).get("filters", ["g", "r"]))


def plot_title(plan: Plan, skymap: SkyMap | None) -> str:
    """Superevent id, else the map's OBJECT (when it is a real id), else the map's file name (escaped: no
    control character; drawn as plain text, never as mathtext: :data:`_PLAIN`)."""
    from .handlers.text import storable

    if skymap is None:
        return storable(plan.event.superevent_id or plan.event.skymap_name or "sky map", 120)
    obj = str(skymap.object_id or "").strip()
    if obj in ("", "0", "None", "UNKNOWN"):
        obj = ""
    name = plan.event.superevent_id or obj or plan.event.skymap_name
    if not name:
        name = "sky map" if skymap.source.startswith("<") else Path(skymap.source).name
    return storable(name, 120)


#: Keywords of a figure text holding words from outside (a title, an answer's reasons): drawn as they are.
_PLAIN = {"parse_math": False}


def plan_picture_png(plan: Plan, skymap: SkyMap | None = None, dpi: int = 100, answer: Any = None,
                     executed: Any = ()) -> bytes:
    """The picture as PNG bytes (:func:`plot_plan`); without a sky map, the airmass panel and timeline only."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fig = _figure(plan, skymap, answer, executed)
    return _render(fig, dpi, "png")


def plot_plan(plan: Plan, skymap: SkyMap, path: str | Path, dpi: int = 120, answer: Any = None,
              executed: Any = ()) -> None:
    """Draw the plan on its sky map, the fields' airmass and the night's timeline; write a PNG.

    Parameters
    ----------
    plan : Plan
        The plan (for a not_observable answer: the plan it replaced).
    skymap : SkyMap
        Its sky map.
    path : str or pathlib.Path
        PNG file to write.
    dpi : int
        Resolution.
    answer : NotObservable, optional
        When given, the title says "not observable" and the reasons are listed.
    executed : sequence of ExecutedExposure
        A re-plan's exposures done before (drawn apart: grey fields, hollow markers).
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ligo.skymap/reproject deprecation chatter
        fig = _figure(plan, skymap, answer, executed)
    _save(fig, path, dpi)


def _zoom_region(prob: np.ndarray, region: np.ndarray, nside: int) -> tuple[float, float, float]:
    """Centre and radius (deg) of the zoom around a region's probability, at least 12 deg, at most 40 deg.

    The centre is the region's probability-weighted mean direction; the radius
    holds 90 % of the region's probability.
    """
    import healpy as hp

    inside = np.flatnonzero(region)
    if inside.size == 0:
        inside = np.array([int(np.argmax(prob))])
    vec = np.asarray(hp.pix2vec(nside, inside, nest=True)).T
    weight = prob[inside] if prob[inside].sum() > 0 else np.ones(inside.size)
    centre = (vec * weight[:, None]).sum(axis=0)
    centre /= np.linalg.norm(centre)
    ra_c, dec_c = (float(np.squeeze(x)) for x in hp.vec2ang(centre, lonlat=True))
    sep = np.degrees(np.arccos(np.clip(vec @ centre, -1.0, 1.0)))
    order = np.argsort(sep)
    cum = np.cumsum(weight[order])
    r90 = float(sep[order][min(np.searchsorted(cum, 0.9 * cum[-1]), len(order) - 1)])
    return ra_c, dec_c, float(min(max(1.3 * r90 + 3.0, ZOOM_MIN_DEG), ZOOM_MAX_DEG))


#: The zoom panel's radius (deg): at least, at most.
ZOOM_MIN_DEG, ZOOM_MAX_DEG = 12.0, 40.0

#: Half the diagonal of a ZTF field (deg; 7.0 x 7.0 deg incl. the chip gaps), with a margin for the zoom's
#: projection: a field whose centre lies this far inside the zoom is drawn whole.
FIELD_HALF_DIAGONAL_DEG = 5.5


def zoom_holding_fields(ra_c: float, dec_c: float, radius: float, ra: np.ndarray,
                        dec: np.ndarray) -> tuple[float, np.ndarray]:
    """The zoom radius widened (up to :data:`ZOOM_MAX_DEG`) to hold the planned fields whole.

    Parameters
    ----------
    ra_c, dec_c, radius : float
        The zoom's centre and radius (deg) from the probability.
    ra, dec : numpy.ndarray
        Planned field centres (deg).

    Returns
    -------
    (float, numpy.ndarray)
        The radius (deg) and a mask of the fields still outside it (too far from the probability's centre:
        the picture names them).
    """
    from astropy.coordinates import angular_separation

    sep = np.degrees(angular_separation(np.radians(ra_c), np.radians(dec_c), np.radians(np.asarray(ra, float)),
                                        np.radians(np.asarray(dec, float))))
    need = np.asarray(sep, float) + FIELD_HALF_DIAGONAL_DEG
    fits = need <= ZOOM_MAX_DEG
    return float(min(max(radius, float(need[fits].max(initial=0.0))), ZOOM_MAX_DEG)), ~fits


def _figure(plan: Plan, skymap: SkyMap | None, answer: Any, executed: Any) -> Any:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    from .plot_airmass import draw_airmass, night_grid

    grid_t = night_grid(plan)
    if skymap is None:
        fig = plt.figure(figsize=(12, 4.8))
        draw_airmass(fig.add_axes([0.07, 0.45, 0.88, 0.42]), plan, grid_t, executed)
        _timeline(fig.add_axes([0.07, 0.14, 0.88, 0.15]), plan, grid_t["hours"], grid_t["sun_alt"])
        fig.text(0.5, 0.95, _headline(plan, plot_title(plan, None)), ha="center", fontsize=11, **_PLAIN)
        return fig
    import ligo.skymap.plot  # noqa: F401  (registers the astro projections)

    grid = load_ztf_fields()
    first_visit: dict[int, float] = {}
    for o in plan.observations:
        first_visit.setdefault(o.field_id, o.start)
    done = sorted({int(e.field_id) for e in executed if getattr(e, "status", "done") in ("done", "ok", "success")}
                  or {int(e.field_id) for e in executed})
    layers, norm = _sky_layers(skymap)
    credible = layers["zoom"][1]
    fig = plt.figure(figsize=(13, 11.5))
    ax_sky = fig.add_axes([0.03, 0.52, 0.50, 0.38], projection="astro hours mollweide")
    ax_zoom = _zoom_axes(fig, grid, skymap, first_visit, credible)
    image = None
    for ax, layer in ((ax_sky, "sky"), (ax_zoom, "zoom")):
        image = _sky_panel(ax, layers[layer], norm, grid, first_visit, plan.observations, done)
    _field_ids(ax_zoom, grid, first_visit)
    for ax in (ax_sky, ax_zoom):
        _bodies(ax, grid_t)
    _style_sky_axes(ax_sky, ax_zoom)
    _colourbar(fig, image, norm)
    _sky_legend(ax_sky, plan, bool(first_visit), bool(done))
    draw_airmass(fig.add_axes([0.06, 0.225, 0.87, 0.17]), plan, grid_t, executed)
    _timeline(fig.add_axes([0.06, 0.05, 0.87, 0.09]), plan, grid_t["hours"], grid_t["sun_alt"])
    _titles(fig, plan, skymap, answer, credible)
    return fig


def _bodies(ax: Any, grid_t: dict[str, Any]) -> None:
    """The Sun and the Moon at the start, on a sky panel (clipped to the panel)."""
    world = ax.get_transform("world")
    for body, style in ((grid_t["sun0"], dict(marker="*", ms=14, color="gold", mec="k")),
                        (grid_t["moon0"], dict(marker="o", ms=10, color="#f5f0c8", mec="#6b5a00"))):
        ax.plot([body.ra.deg], [body.dec.deg], transform=world, mew=0.8, ls="none", clip_on=True, **style)


def _field_ids(ax: Any, grid: Any, first_visit: dict[int, float]) -> None:
    """Each planned field's id at its centre (zoom panel)."""
    import matplotlib.patheffects as pe

    world = ax.get_transform("world")
    for fid in first_visit:
        k = grid.index_of(np.array([fid]))[0]
        ax.text(grid.ra[k], grid.dec[k], str(fid), transform=world, fontsize=7, ha="center", va="center",
                color="#0b2a6f", clip_on=True, path_effects=[pe.withStroke(linewidth=2.2, foreground="white")])


def _sky_layers(skymap: SkyMap) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], Any]:
    """Probability per deg² and credible levels (%) of the two sky panels, and their one colour scale.

    The all-sky panel (``sky``) is drawn at a coarser resolution (NSIDE 64 at most), the zoom at the map's.
    """
    import healpy as hp
    from ligo.skymap.postprocess import find_greedy_credible_levels
    from matplotlib.colors import Normalize

    prob = skymap.prob
    coarse_nside = min(skymap.nside, 64)
    coarse = hp.ud_grade(prob, coarse_nside, order_in="NESTED", order_out="NESTED", power=-2)
    layers = {
        "sky": (coarse / hp.nside2pixarea(coarse_nside, degrees=True), 100.0 * find_greedy_credible_levels(coarse)),
        "zoom": (prob / hp.nside2pixarea(skymap.nside, degrees=True), 100.0 * find_greedy_credible_levels(prob)),
    }
    return layers, Normalize(vmin=0.0, vmax=float(layers["zoom"][0].max()))


def _zoom_axes(fig: Any, grid: Any, skymap: SkyMap, first_visit: dict[int, float], credible: np.ndarray) -> Any:
    """The zoom panel: on the probability the plan covers, else on the 90 % credible region."""
    from astropy import units as u
    from astropy.coordinates import SkyCoord

    prob = skymap.prob
    if first_visit:
        from .scheduler_core.sky.fields import field_footprints

        covered = np.zeros(prob.size, dtype=bool)
        covered[field_footprints(grid, skymap.nside).union(list(first_visit))] = True
        ra_c, dec_c, radius = _zoom_region(prob, covered & (prob > 0), skymap.nside)
        ids = np.array(list(first_visit), dtype=int)
        rows = grid.index_of(ids)
        radius, outside = zoom_holding_fields(ra_c, dec_c, radius, grid.ra[rows], grid.dec[rows])
    else:
        ra_c, dec_c, radius = _zoom_region(prob, credible <= 90.0, skymap.nside)
        ids, outside = np.array([], dtype=int), np.array([], dtype=bool)
    ax = fig.add_axes([0.60, 0.49, 0.33, 0.41], projection="astro degrees zoom",
                      center=SkyCoord(ra_c * u.deg, dec_c * u.deg), radius=radius * u.deg)
    if outside.any():
        far = ids[outside].tolist()
        named = ", ".join(map(str, far[:8])) + (f" and {len(far) - 8} more" if len(far) > 8 else "")
        ax.text(0.02, 0.98, f"{len(far)} field{'s' if len(far) > 1 else ''} outside this zoom"
                f" (see the whole sky):\n{named}", transform=ax.transAxes, fontsize=7, ha="left", va="top", color="#0b2a6f",
                zorder=6, bbox=dict(boxstyle="round,pad=0.25", fc="white", ec="#0b2a6f", lw=0.6, alpha=0.9))
    return ax


def _sky_panel(ax: Any, layer: tuple[np.ndarray, np.ndarray], norm: Any, grid: Any, first_visit: dict[int, float],
               obs: Any, done: Any = ()) -> Any:
    """One sky panel: the probability, the 50 % and 90 % contours, the fields outlined, the executed fields
    filled grey, the path; the image."""
    import matplotlib.patheffects as pe

    density, levels = layer
    image = ax.imshow_hpx((density, "ICRS"), nested=True, cmap="cylon", vmin=norm.vmin, vmax=norm.vmax)
    ax.contour_hpx((levels, "ICRS"), nested=True, levels=[50.0, 90.0], colors="black",
                   linewidths=[1.1, 0.9], linestyles=["solid", "dashed"])
    ax.grid(alpha=0.3)
    world = ax.get_transform("world")
    for fid in done:
        k = grid.index_of(np.array([fid]))[0]
        ra, dec = _outline(grid.ra[k], grid.dec[k])
        if not np.isnan(ra).any():
            ax.fill(ra, dec, transform=world, facecolor=EXECUTED_COLOUR, alpha=0.55, edgecolor="#555555", lw=0.7)
    for fid in first_visit:
        k = grid.index_of(np.array([fid]))[0]
        ra, dec = _outline(grid.ra[k], grid.dec[k])
        ax.plot(ra, dec, transform=world, color="#3b6fd6", lw=0.9, alpha=0.9)
    edge = [pe.withStroke(linewidth=3.0, foreground="white")]
    # the observing path: a segment into each visit, in the colour of the visit's filter
    for a, b in zip(obs[:-1], obs[1:]):
        if a.block != b.block or abs(a.ra - b.ra) > 180.0:
            continue  # within a block only (blocks are hours apart), never across RA = 0h
        ls = "-" if b.filter == obs[0].filter else (0, (3, 2))
        ax.plot([a.ra, b.ra], [a.dec, b.dec], transform=world, color=FILTER_COLOURS.get(b.filter, "k"),
                lw=1.4, ls=ls, path_effects=edge)
    if obs:
        ax.plot([obs[0].ra], [obs[0].dec], transform=world, marker="o", ms=6, mfc="none", mec="k", mew=1.5)
    return image


def _style_sky_axes(ax_sky: Any, ax_zoom: Any) -> None:
    """Tick labels of both sky panels; the zoom's always bottom and left, in degrees."""
    ax_sky.coords[0].set_ticklabel(size=8)
    ax_sky.coords[1].set_ticklabel(size=8)
    ax_zoom.coords[0].set_ticks(number=5)
    ax_zoom.coords[1].set_ticks(number=5)
    ax_zoom.coords[0].set_major_formatter("d")
    ax_zoom.coords[1].set_major_formatter("d")
    ax_zoom.coords[0].set_ticklabel(size=8, exclude_overlapping=True)
    ax_zoom.coords[1].set_ticklabel(size=8)
    ax_zoom.coords[0].set_ticklabel_position("b")  # never on top, whatever the field's declination
    ax_zoom.coords[1].set_ticklabel_position("l")
    ax_zoom.coords[0].set_axislabel_position("b")
    ax_zoom.coords[1].set_axislabel_position("l")
    ax_zoom.coords[0].set_axislabel("RA (deg)")
    ax_zoom.coords[1].set_axislabel("Dec (deg)")


def _colourbar(fig: Any, image: Any, norm: Any) -> None:
    """The probability scale of both sky panels, in units of a power of ten."""
    from matplotlib.ticker import FuncFormatter

    cax = fig.add_axes([0.945, 0.52, 0.012, 0.36])
    exponent = int(np.floor(np.log10(norm.vmax))) if norm.vmax > 0 else 0
    cb = fig.colorbar(image, cax=cax, format=FuncFormatter(lambda v, _: f"{v / 10.0 ** exponent:.1f}"))
    cb.set_label(f"probability per deg² (×10$^{{{exponent}}}$)", fontsize=9)
    cb.ax.tick_params(labelsize=8)


def _sky_legend(ax_sky: Any, plan: Plan, has_fields: bool, has_done: bool = False) -> None:
    """Contours, fields, the executed fields, the path per filter, the Sun and the Moon, below the all-sky panel."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    legend = [Line2D([], [], color="k", lw=1.1, label="50 % credible"),
              Line2D([], [], color="k", ls="--", lw=0.9, label="90 % credible")]
    if has_fields:
        legend.append(Line2D([], [], color="#3b6fd6", lw=0.9, label="planned field (id in the zoom)"))
    if has_done:
        legend.append(Patch(facecolor=EXECUTED_COLOUR, alpha=0.55, edgecolor="#555555", label="executed before"))
    legend += [Line2D([], [], color=FILTER_COLOURS[f], lw=1.3, ls="-" if i == 0 else (0, (3, 2)),
                      label=f"path to the {f} visits")
               for i, f in enumerate(dict.fromkeys(o.filter for o in plan.observations))]
    legend += [Line2D([], [], color="gold", marker="*", ms=10, mec="k", ls="none", label="Sun at start"),
               Line2D([], [], color="#f5f0c8", marker="o", ms=8, mec="#6b5a00", ls="none", label="Moon at start")]
    ax_sky.legend(handles=legend, loc="upper left", bbox_to_anchor=(0.0, -0.02), ncol=3, fontsize=8,
                  frameon=False)


def _timeline(ax_t: Any, plan: Plan, hours: np.ndarray, sun_alt: np.ndarray) -> None:
    """The horizon: day, twilight and night, and every exposure by filter."""
    obs = plan.observations
    sun_limit = float((plan.config or {}).get("sun_alt_max_deg", -12.0))
    night = sun_alt <= sun_limit
    twilight = (sun_alt < 0) & ~night
    dt = float(hours[1] - hours[0]) if hours.size > 1 else 1.0
    for mask, colour in ((twilight, SKY_SHADES["twilight"]), (night, SKY_SHADES["night"])):
        ax_t.broken_barh([(h - dt / 2, dt) for h in hours[mask]], (0.4, len(filters_of(plan)) + 0.2),
                         color=colour, lw=0, antialiased=False)
    filters = filters_of(plan)
    for row, f in enumerate(filters):
        bars = [(o.start / 3600.0, o.exposure_s / 3600.0) for o in obs if o.filter == f]
        ax_t.broken_barh(bars, (row + 0.6, 0.8), color=FILTER_COLOURS.get(f, "k"))
    ax_t.set_ylim(0.4, len(filters) + 0.6)
    ax_t.set_yticks([r + 1 for r in range(len(filters))], [f"{f} exposures" for f in filters], fontsize=8)
    _time_axis(ax_t, plan, hours[-1])
    _timeline_legend(ax_t, plan, filters, sun_limit)


def _time_axis(ax_t: Any, plan: Plan, span_h: float) -> None:
    """Hours after the start, with the UTC clock time under each tick."""
    from astropy import units as u

    ax_t.set_xlim(0, span_h)
    step = 1 if span_h <= 12 else 2 if span_h <= 30 else 6
    ticks = np.arange(0, span_h + 1e-9, step)
    labels = [(plan.start + t * u.hour).utc.isot[11:16] for t in ticks]
    ax_t.set_xticks(ticks, [f"{int(t)} h\n{lab}" for t, lab in zip(ticks, labels)], fontsize=8)
    ax_t.set_xlabel(f"hours after {plan.start.utc.isot[:16]} UTC (and UTC clock time)", fontsize=9)


def _timeline_legend(ax_t: Any, plan: Plan, filters: list[str], sun_limit: float) -> None:
    from matplotlib.patches import Patch

    obs = plan.observations
    handles = [Patch(color=SKY_SHADES["twilight"], label="twilight"),
               Patch(color=SKY_SHADES["night"], label=f"night (Sun < {sun_limit:g}°)")]
    handles += [Patch(color=FILTER_COLOURS.get(f, "k"), label=f"{f}") for f in filters if any(o.filter == f for o in obs)]
    ax_t.legend(handles=handles, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=len(handles), fontsize=8,
                frameon=False)


def _titles(fig: Any, plan: Plan, skymap: SkyMap, answer: Any, credible: np.ndarray) -> None:
    """The plan in one line (or "not observable" and why), and what the panels show."""
    import healpy as hp

    m = plan.metrics
    title = plot_title(plan, skymap)
    if answer is not None:
        head = f"{title}: NOT OBSERVABLE by ZTF from {plan.start.utc.isot[:16]} UTC " \
               f"(best coverage {m.coverage:.4f} < {answer.min_coverage:g})"
        fig.text(0.5, 0.955, head, ha="center", fontsize=12, color="#a00000", **_PLAIN)
        fig.text(0.5, 0.925, "; ".join(answer.sentences[:2]), ha="center", fontsize=8.5, wrap=True, **_PLAIN)
    else:
        fig.text(0.5, 0.955, _headline(plan, title), ha="center", fontsize=12, **_PLAIN)
        area = float((credible <= 90.0).sum()) * hp.nside2pixarea(skymap.nside, degrees=True)
        fig.text(0.5, 0.925, f"90 % credible area {area:.0f} deg²; fields outlined, path in filter colours "
                             "(circle: first visit)", ha="center", fontsize=9)


def _headline(plan: Plan, title: str) -> str:
    """The title line: fields, exposures and the total coverage (a re-plan: what was done, added, total)."""
    m = plan.metrics
    if m.coverage_executed is not None:
        covered = (f"total coverage {m.coverage + m.coverage_executed:.1%} ({m.coverage_executed:.1%} done before "
                   f"+ {m.coverage:.1%} added)")
    else:
        covered = f"coverage {m.coverage:.1%}"
    return (f"{title}: {m.n_fields} fields, {m.n_exposures} exposures, {covered}; "
            f"start {plan.start.utc.isot[:16]} UTC")


def _render(fig: Any, dpi: int, fmt: str) -> bytes:
    import io

    from matplotlib import pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format=fmt)
    plt.close(fig)
    return buf.getvalue()


def _save(fig: Any, path: str | Path, dpi: int) -> None:
    """Render the figure, then write it whole (a device or a symlink is never replaced)."""
    from .outputs import write_bytes_atomic

    write_bytes_atomic(path, _render(fig, dpi, Path(path).suffix.lstrip(".").lower() or "png"))
