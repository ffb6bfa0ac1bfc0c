"""The depth model (D1-D2, ``scheduler_core/source/depth.py``) against ZTF's published depths, and its picture.

Writes ``benchmarks/results/science/depth_model/``: ``calibration.md`` (the table of
``docs/design/detection.md`` §2.1: model medians beside every published figure,
with the exposure time and the conditions each refers to, and the GW190425
time budget), ``calibration.csv`` (the same numbers) and ``depth_model.png``
(the 300 s and 30 s difference-image depth against the Moon's separation and
against airmass, g and r, four Moon phases, the published figures marked).

    PYTHONPATH=. .venv/bin/python benchmarks/science/depth_model.py [OUTDIR]
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
from astropy.time import Time

from mushrooms.scheduler_core.sky.fields import load_ztf_fields
from mushrooms.scheduler_core.source.depth import SkyConditions, limiting_magnitude, science_depth, sky_conditions

FIELDS = ("airmass", "moon_alt_deg", "moon_sep_deg", "moon_phase_deg", "sun_alt_deg")
#: GW190425: merger 2019-04-25 08:18:05 UTC (Coughlin et al. 2019); ZTF covered ~8000 deg² in g and r
#: over the next two nights (abstract).  A ZTF field covers ~47 deg².
GW190425_MERGER = "2019-04-25T08:18:05"
GW190425_AREA_DEG2 = 8000.0
ZTF_FIELD_DEG2 = 47.0
#: Overheads per exposure (s): readout 8 s + a short slew (ztf_sim's readout; ~10 s between neighbours).
OVERHEAD_S = 18.0


def _pointings(jd: np.ndarray, airmass_max: float = 2.0) -> SkyConditions:
    """ZTF grid fields at the times ``jd`` with the Sun below -12 deg, airmass <= airmass_max, Moon >= 20 deg away."""
    grid = load_ztf_fields()
    cond = sky_conditions(grid.ra[:, None], grid.dec[:, None], Time(jd, format="jd", scale="utc"))
    ok = (cond.sun_alt_deg < -12) & (cond.airmass <= airmass_max) & (cond.moon_sep_deg >= 20)
    return SkyConditions(*(np.asarray(getattr(cond, f))[ok] for f in FIELDS))


def _medians(cond: SkyConditions, exposure_s: float) -> dict[str, float]:
    n = np.asarray(cond.airmass).size
    out = {}
    for band in "gr":
        out[f"sci_{band}"] = float(np.median(science_depth(np.full(n, band), exposure_s, cond)))
        out[f"diff_{band}"] = float(np.median(limiting_magnitude(np.full(n, band), exposure_s, cond)))
    return out


def _night_hours(start: str, end: str) -> float:
    """Hours with the Sun below -12 deg at Palomar between two UTC times."""
    jd = np.arange(Time(start, scale="utc").jd, Time(end, scale="utc").jd, 1.0 / 1440.0)
    sun = np.asarray(sky_conditions(np.array([0.0]), np.array([0.0]), Time(jd, format="jd", scale="utc")).sun_alt_deg)
    return float((sun.ravel() < -12.0).sum()) / 60.0


def gw190425_budget() -> dict[str, float]:
    """Night hours after GW190425 and the longest mean exposure they allow for 8000 deg² in g and r.

    Two readings of "the next two nights": the rest of the merger's night and
    the next one (strict), or the two full nights after the merger (generous).
    """
    exposures = 2.0 * GW190425_AREA_DEG2 / ZTF_FIELD_DEG2  # one g and one r per field, the fewest possible
    strict = _night_hours(GW190425_MERGER, "2019-04-26T18:00:00")
    generous = _night_hours("2019-04-25T18:00:00", "2019-04-27T18:00:00")
    return {"exposures": exposures, "night_h_strict": strict, "night_h_generous": generous,
            "max_mean_exposure_s_strict": strict * 3600.0 / exposures - OVERHEAD_S,
            "max_mean_exposure_s": generous * 3600.0 / exposures - OVERHEAD_S}


def calibration_rows() -> list[dict[str, object]]:
    """One row per published figure: the source, its exposure, the published depth, the model's medians."""
    rng = np.random.default_rng(2019)
    year = _pointings(Time("2019-01-01T00:00:00", scale="utc").jd + rng.random(500) * 365.25)
    nights = _pointings(np.concatenate([Time(d, scale="utc").jd + np.linspace(0.0, 0.30, 40)
                                        for d in ("2019-04-25T04:00:00", "2019-04-26T04:00:00")]))
    budget = gw190425_budget()
    rows: list[dict[str, object]] = []

    def row(source: str, kind: str, exposure: str, published: str, cond: SkyConditions, t: float, image: str,
            target: float | None) -> None:
        m = _medians(cond, t)
        g, r = m[f"{image}_g"], m[f"{image}_r"]
        rows.append({"source": source, "kind": kind, "exposure": exposure, "published": published,
                     "model_at_s": t, "image": image, "model_g": round(g, 2), "model_r": round(r, 2),
                     "model_minus_published": None if target is None else
                     f"{g - target:+.2f} / {r - target:+.2f}" if kind != "r" else f"{r - target:+.2f}"})

    row("Bellm et al. 2019; Masci et al. 2019 (ZTF medians, g/r)", "g/r", "30 s (stated)", "g 20.8 / r 20.6",
        year, 30.0, "sci", None)
    rows[-1]["model_minus_published"] = f"{rows[-1]['model_g'] - 20.8:+.2f} / {rows[-1]['model_r'] - 20.6:+.2f} (fitted)"
    row("ZTF technical specification (median single visit, all lunar phases)", "r", "30 s (stated)", "20.4 (R)",
        year, 30.0, "diff", 20.4)
    row("gwemopt ZTF.config (filt r, magnitude, exposuretime)", "r", "30 s (stated)", "20.4", year, 30.0, "diff", 20.4)
    row("GCN Circ. 25418 (ZTF survey, 'typical depth')", "g/r", "30 s (stated)", "~20.5", year, 30.0, "diff", 20.5)
    for t in (30.0, 120.0, 180.0, 300.0):
        row("Coughlin et al. 2019, GW190425 (8000 deg², two nights)", "g/r",
            f"not stated; time budget <= {budget['max_mean_exposure_s']:.0f} s mean", "≈ 21",
            nights, t, "diff", 21.0)
    for t in (30.0, 60.0, 180.0, 300.0):
        row("Kasliwal et al. 2020, 13 O3 triggers (median)", "g/r", "not stated", "20.8", year, t, "diff", 20.8)
    return rows


def write_table(rows: list[dict[str, object]], out: Path) -> None:
    budget = gw190425_budget()
    with open(out / "calibration.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = ["| source | exposure | published | model at | image | model g / r | model − published (g / r) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['source']} | {r['exposure']} | {r['published']} | {r['model_at_s']:.0f} s | "
                     f"{'science (D1)' if r['image'] == 'sci' else 'difference (D2)'} | "
                     f"{r['model_g']:.2f} / {r['model_r']:.2f} | {r['model_minus_published']} |")
    lines += ["", f"GW190425 time budget: {budget['exposures']:.0f} exposures at least (8000 deg² / 47 deg² per field, "
              f"one g and one r each) in {budget['night_h_strict']:.1f} h with the Sun below -12° (the rest of the "
              f"merger's night and the next) or {budget['night_h_generous']:.1f} h (the two full nights after it): at "
              f"most {budget['max_mean_exposure_s_strict']:.0f} s or {budget['max_mean_exposure_s']:.0f} s per exposure "
              f"on average with {OVERHEAD_S:.0f} s of overhead each, if ZTF did nothing else on those nights.",
              "", "Model medians: ZTF grid fields at random night times of 2019 (500 times; Sun < -12°, airmass ≤ 2, "
              "Moon ≥ 20° away), or at 40 times each on the nights of 2019-04-25 and -26 (04:00-11:12 UTC)."]
    (out / "calibration.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def _cond(airmass: np.ndarray, sep: np.ndarray, phase: float, moon_alt: float = 45.0) -> SkyConditions:
    shape = np.broadcast_shapes(np.shape(airmass), np.shape(sep))
    return SkyConditions(airmass=np.broadcast_to(np.asarray(airmass, float), shape),
                         moon_alt_deg=np.full(shape, moon_alt if phase < 180 else -30.0),
                         moon_sep_deg=np.broadcast_to(np.asarray(sep, float), shape),
                         moon_phase_deg=np.full(shape, float(phase)), sun_alt_deg=np.full(shape, -30.0))


def picture(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phases = ((180.0, "new Moon (set)", "k"), (120.0, "crescent, 25 % lit", "tab:blue"),
              (90.0, "quarter, 50 % lit", "tab:orange"), (0.0, "full", "tab:red"))
    sep = np.linspace(20.0, 150.0, 131)
    x = np.linspace(1.0, 2.5, 151)
    fig, axes = plt.subplots(2, 2, figsize=(12, 9.5), sharey="row")
    for i, band in enumerate("gr"):
        ax_sep, ax_x = axes[i]
        for phase, label, colour in phases:
            for t, style in ((300.0, "-"), (30.0, ":")):
                ax_sep.plot(sep, limiting_magnitude(np.full(sep.size, band), t, _cond(1.2, sep, phase)), style,
                            color=colour, label=f"{label}, {t:.0f} s" if i == 0 else None)
                ax_x.plot(x, limiting_magnitude(np.full(x.size, band), t, _cond(x, 60.0, phase)), style, color=colour)
            ax_x.plot(x, science_depth(np.full(x.size, band), 300.0, _cond(x, 60.0, phase)), "--", color=colour,
                      lw=0.8, alpha=0.6)
        pub30 = {"g": 20.8, "r": 20.6}[band]
        for ax, xpos, side in ((ax_sep, 140.0, "right"), (ax_x, 1.345, "left")):
            ax.axhline(pub30, color="0.4", lw=0.8)
            ax.plot([xpos], [pub30], "s", color="0.3", ms=7)
            shift = -8 if side == "right" else 8
            ax.annotate(f"ZTF 30 s median, science image ({pub30})", (xpos, pub30), textcoords="offset points",
                        xytext=(shift, -13), ha=side, fontsize=8)
            if band == "r":
                ax.plot([xpos], [20.4], "D", color="tab:purple", ms=6)
                ax.annotate("30 s difference image: spec, gwemopt (20.4)", (xpos, 20.4), textcoords="offset points",
                            xytext=(shift, -12), ha=side, fontsize=8, color="tab:purple")
            ax.axhspan(20.8, 21.0, color="tab:green", alpha=0.15)
            ax.text(0.02, 0.03 if band == "g" else 0.2, "GW campaigns' medians 20.8 (O3) - ≈21 (GW190425), "
                    "exposure not stated", transform=ax.transAxes, fontsize=8, color="tab:green")
        ax_sep.set_title(f"{band}: depth against the Moon's separation (airmass 1.2, Moon 45° up)")
        ax_x.set_title(f"{band}: depth against airmass (Moon 60° away, 45° up)")
        ax_sep.set_xlabel("Moon separation (deg)")
        ax_x.set_xlabel("airmass")
        ax_sep.set_ylabel(f"{band} 5σ limiting magnitude (AB)")
        for ax in (ax_sep, ax_x):
            ax.grid(alpha=0.3)
            ax.set_ylim(18.4, 23.0)
    fig.legend(*axes[0, 0].get_legend_handles_labels(), fontsize=8, ncol=4, loc="lower center")
    axes[0, 1].text(0.98, 0.97, "solid 300 s, dotted 30 s: difference image (D2)\ndashed thin: 300 s science image (D1)",
                    transform=axes[0, 1].transAxes, ha="right", va="top", fontsize=8)
    fig.suptitle("ZTF depth model (docs/design/detection.md D1-D2): dark sky, Moon (Krisciunas & Schaefer 1991), "
                 "airmass, reference images", fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(out / "depth_model.png", dpi=110)


def main(argv: list[str]) -> int:
    out = Path(argv[1] if len(argv) > 1 else "benchmarks/results/science/depth_model")
    out.mkdir(parents=True, exist_ok=True)
    write_table(calibration_rows(), out)
    picture(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
