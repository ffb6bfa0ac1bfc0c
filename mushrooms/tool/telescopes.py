"""``mushrooms telescopes [NAME] [--json]``: the telescopes mushrooms knows, or one description's details.

Without NAME: one line per shipped description (``scheduler_core/data/telescopes/``):
name, site, field of view, number of fields, filters, queue kind and
source.  With NAME (a shipped name or the path of a description file): the
whole description, value group by value group, each with its source.
``--json``: the same as one JSON document.  A description that cannot be
read is bad input: one line per problem on stderr, exit status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, Sequence

from .common import EXIT_INPUT, add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main", "describe", "listing"]

HELP = "list the telescopes mushrooms knows, or show one description (site, grid, filters, overheads, limits)"


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms telescopes`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("telescopes", HELP)
    p.add_argument("name", nargs="?", metavar="NAME", help="a telescope (ztf, ls4, winter, decam) or a description "
                   "file (.toml): show it in full")
    p.add_argument("--json", action="store_true", help="one JSON document on stdout (for scripts)")
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms telescopes`` on its own."""
    return execute("telescopes", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """List or show; 0 done, 2 a description that cannot be read (one line per problem)."""
    from ..scheduler_core.instruments import DescriptionError, known_telescopes, load_description

    try:
        if args.name:
            desc = load_description(args.name)
            print(json.dumps(describe(desc), indent=1) if args.json else render_one(desc))
        else:
            descs = [load_description(n) for n in known_telescopes()]
            print(json.dumps([d.summary() for d in descs], indent=1) if args.json else listing(descs))
    except DescriptionError as exc:
        for line in exc.problems:
            print(f"mushrooms telescopes: error: {line}", file=sys.stderr)
        return EXIT_INPUT
    return 0


def listing(descs: Sequence[Any]) -> str:
    """One line per description: name, site, field of view, fields, filters, queue, source."""
    rows = [("name", "site (lat, lon deg; height m)", "FoV deg2", "fields", "filters", "queue", "source")]
    for d in descs:
        s = d.site
        rows.append((d.name, f"{s.latitude_deg:+.4f}, {s.longitude_deg:+.4f}; {s.height_m:.0f}",
                     f"{d.field_of_view_deg2:.2f}", str(len(d.grid)), " ".join(d.filters), d.queue, d.source))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)) + "  " + r[-1] for r in rows)


def _num(x: float | None, unit: str = "") -> str:
    return "-" if x is None else f"{x:g}{unit}"


def _filter_line(f: Any, exposure_s: float) -> str:
    ref = (f"reference {f.reference_depth:g} mag, {f.reference_fwhm_arcsec:g}\"" if f.reference_depth is not None
           else "no reference term")
    det = f"detectors {', '.join(map(str, f.detectors))}" if f.detectors else "all detectors"
    ids = "".join([f", queue id {f.queue_id}" if f.queue_id is not None else "",
                   f", SkyPortal {f.skyportal_name}" if f.skyportal_name else ""])
    return (f"  {f.name}: depth {f.zenith_depth:g} mag in {exposure_s:g} s (zenith, dark), sky {f.sky_zenith:g} "
            f"mag/arcsec2, k {f.extinction:g} mag/airmass, FWHM {f.zenith_fwhm_arcsec:g}\", Sun-V "
            f"{f.sun_minus_v:+g}, {ref}; {det}{ids}\n    source: {f.source}")


def render_one(d: Any) -> str:
    """The whole description as text, group by group, each with its source."""
    s, g, fp, o, lim, p, e = d.site, d.grid, d.footprint, d.overheads, d.limits, d.planning, d.execution
    axes = "; ".join(f"{a.coordinate} {a.accel_deg_s2:g} deg/s2, {a.vmax_deg_s:g} deg/s" for a in o.axes)
    boxes = "".join(f"\n  keep out {b.ha_min_deg:g} < HA < {b.ha_max_deg:g}, {b.dec_min_deg:g} < Dec < "
                    f"{b.dec_max_deg:g} deg: {b.why}" for b in lim.keep_out)
    lines = [
        f"{d.name}: {d.title}", f"  file: {d.path}", f"  queue: {d.queue}", f"  source: {d.source}",
        f"site: {s.latitude_deg}, {s.longitude_deg} deg, {s.height_m:g} m; night anchor {s.night_anchor_utc} UTC",
        f"  source: {s.source}",
        f"grid: {len(g)} fields ({g.origin}), Dec {g.dec.min():+.2f} to {g.dec.max():+.2f} deg", f"  source: {g.source}",
        f"footprint: {len(fp.polygons)} detectors, {fp.area_deg2:.2f} deg2, within {fp.radius_deg:g} deg of the "
        f"pointing", f"  source: {fp.source}",
        f"filters ({d.depth.reference_exposure_s:g} s reference; seeing X^{d.depth.seeing_airmass_exponent:g}, "
        f"twilight {d.depth.twilight_slope_mag_per_deg:.4g} mag/deg):",
        *[_filter_line(f, d.depth.reference_exposure_s) for f in d.filters.values()],
        f"  source: {d.depth.source}",
        f"overheads: readout {o.readout_s:g} s, settle {o.settle_s:g} s, filter change {o.filter_change_s:g} s "
        f"({'during' if o.filter_change_with_slew else 'before'} the slew); axes: {axes}", f"  source: {o.source}",
        f"limits: airmass <= {lim.airmass_max:g}, |HA| <= {lim.ha_max_h:g} h, Dec {lim.dec_min_deg:g} to "
        f"{lim.dec_max_deg:g} deg, Sun <= {lim.sun_alt_max_deg:g} deg, Moon >= {lim.moon_sep_min_deg:g} deg{boxes}",
        f"  source: {lim.source}",
        f"planning: {p.exposure_s:g} s exposures ({p.exposure_min_s:g} to {p.exposure_max_s:g} s), filters "
        f"{'-'.join(p.filters)}, cadence {p.cadence_s:g} s, filter change {p.filter_change_s:g} s, slew estimate "
        f"{p.slew_estimate_s:g} s", f"  source: {p.source}",
        f"execution: {_execution_text(e)}", f"  source: {e.source}",
    ]
    return "\n".join(lines)


def _execution_text(e: Any) -> str:
    if e.queue == "ztf_too":
        programs = ", ".join(f"{k} {v}" for k, v in e.program_ids.items())
        return (f"ZTF ToO queue; survey step {_num(e.survey_step_s, ' s')}, slew after the survey "
                f"{_num(e.lost_pointing_slew_s, ' s')}, default max airmass {_num(e.default_max_airmass)}; "
                f"programs {programs}")
    if e.queue == "skyportal":
        return f"SkyPortal observation plan for instrument {e.skyportal_instrument}"
    return f"target list ({', '.join(e.formats)})"


def describe(d: Any) -> dict[str, Any]:
    """The description as JSON-ready data (the grid as its size and extent, the footprint's polygons in full)."""
    out = {"name": d.name, "title": d.title, "source": d.source, "path": d.path, "queue": d.queue,
           "site": _plain(d.site),
           "grid": {"fields": len(d.grid), "origin": d.grid.origin, "dec_min_deg": float(d.grid.dec.min()),
                    "dec_max_deg": float(d.grid.dec.max()), "first_id": int(d.grid.ids[0]), "source": d.grid.source},
           "footprint": {"detectors": len(d.footprint.polygons), "area_deg2": d.footprint.area_deg2,
                         "radius_deg": d.footprint.radius_deg,
                         "polygons": [p.tolist() for p in d.footprint.polygons], "source": d.footprint.source},
           "filters": _plain(d.filters)}
    for group in ("depth", "overheads", "limits", "planning", "execution"):
        out[group] = _plain(getattr(d, group))
    return out


def _plain(value: Any) -> Any:
    """Dataclasses, mappings and tuples as dicts and lists; ``inf`` as ``"inf"``/``"-inf"`` (JSON has none)."""
    import dataclasses
    from collections.abc import Mapping

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and value in (float("inf"), float("-inf")):
        return "inf" if value > 0 else "-inf"
    return value
