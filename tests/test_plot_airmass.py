"""The airmass panel's time axis: the night of the exposures, not the whole horizon."""

from __future__ import annotations

import numpy as np

from mushrooms.plot_airmass import _dark_span


def test_the_axis_spans_the_night_holding_the_exposures_not_the_dawn_of_the_start():
    hours = np.arange(0.0, 24.0, 0.1)
    dark = (hours < 0.7) | ((hours >= 15.0) & (hours < 23.5))  # the end of one night, then the next night
    lo, hi = _dark_span(hours, dark, [18.6, 18.7, 20.0, 20.1])
    assert lo == np.float64(15.0) and 23.3 < hi < 23.5


def test_exposures_outside_the_dark_hours_widen_the_axis_and_none_shows_the_longest_night():
    hours = np.arange(0.0, 24.0, 0.1)
    dark = (hours < 0.7) | ((hours >= 15.0) & (hours < 23.5))
    assert _dark_span(hours, dark, [14.0, 14.2, 16.0])[0] == 14.0  # a twilight exposure stays in view
    lo, hi = _dark_span(hours, dark, [])
    assert lo == 15.0 and hi > 23.3


def test_field_ids_of_exposures_close_in_time_and_airmass_do_not_cover_each_other():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mushrooms.plot_airmass import place_field_labels

    fig, ax = plt.subplots(figsize=(11.6, 1.7), dpi=120)
    ax.set_xlim(2.0, 14.0)
    ax.set_ylim(2.6, 1.0)
    # a cluster like G476954's first hour: five first exposures within 20 min and 0.3 in airmass
    labels = [("312", 3.55, 1.72), ("1355", 3.62, 1.66), ("1354", 3.70, 1.78), ("311", 3.58, 1.84),
              ("1303", 3.50, 1.94), ("262", 3.63, 2.07), ("1532", 7.5, 2.35)]
    place_field_labels(ax, labels)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    assert sorted(t.get_text() for t in ax.texts) == sorted(text for text, _, _ in labels)
    overlaps = [(ax.texts[i].get_text(), ax.texts[j].get_text()) for i in range(len(boxes))
                for j in range(i + 1, len(boxes)) if boxes[i].overlaps(boxes[j])]
    assert overlaps == []
    plt.close(fig)


def test_the_zoom_widens_to_hold_planned_fields_whole_and_names_those_too_far():
    from mushrooms.plotting import FIELD_HALF_DIAGONAL_DEG, ZOOM_MAX_DEG, zoom_holding_fields

    ra = np.array([120.0, 135.0, 280.0])
    dec = np.array([-20.0, 0.0, -10.0])
    radius, outside = zoom_holding_fields(120.0, -20.0, 12.0, ra, dec)
    assert outside.tolist() == [False, False, True]  # 160 deg away: the whole sky shows it
    near = float(np.degrees(np.arccos(np.sin(np.radians(0.0)) * np.sin(np.radians(-20.0))
                                      + np.cos(np.radians(0.0)) * np.cos(np.radians(-20.0))
                                      * np.cos(np.radians(15.0)))))
    assert abs(radius - (near + FIELD_HALF_DIAGONAL_DEG)) < 1e-9
    assert radius <= ZOOM_MAX_DEG
    assert zoom_holding_fields(120.0, -20.0, 30.0, ra[:1], dec[:1])[0] == 30.0  # never narrower than the map asks


def _span_colour(ax, hour: float) -> str | None:
    """The colour of the shaded span of ``ax`` (axvspan, zorder 0) over ``hour``, None when unshaded."""
    from matplotlib.colors import to_hex

    for patch in ax.patches:
        if patch.get_zorder() != 0:
            continue
        x0, x1 = sorted(float(v) for v in patch.get_path().transformed(patch.get_patch_transform()).vertices[:, 0]
                        [[0, 2]])
        if x0 <= hour < x1:
            return to_hex(patch.get_facecolor())
    return None


def test_night_and_twilight_have_one_colour_each_in_the_airmass_panel_and_the_timeline_below():
    """The timeline's legend says which shade is night and which twilight; the airmass panel above it must
    shade them in the same colours (it shaded night in the colour the legend gives twilight)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.colors import to_hex
    from matplotlib import pyplot as plt
    from pathlib import Path

    from mushrooms.plot_airmass import night_grid
    from mushrooms.plotting import _figure
    from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap

    skymap = Path(__file__).resolve().parent / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    plan = make_plan(read_skymap(skymap, nside=64), PlanningConfig(solver="greedy", nside=64))
    fig = _figure(plan, None, None, ())
    try:
        airmass = next(ax for ax in fig.axes if ax.get_ylabel() == "airmass")
        timeline = next(ax for ax in fig.axes if ax.get_legend() and "twilight" in
                        [t.get_text() for t in ax.get_legend().get_texts()])
        legend = {t.get_text().split(" ")[0]: to_hex(h.get_facecolor())
                  for t, h in zip(timeline.get_legend().get_texts(), timeline.get_legend().legend_handles)}
        grid = night_grid(plan)
        limit = float(plan.config.get("sun_alt_max_deg", -12.0))
        dark = grid["hours"][int(grid["sun_alt"].argmin())]
        dusk = grid["hours"][int(((grid["sun_alt"] < 0) & (grid["sun_alt"] > limit + 1)).argmax())]
        assert _span_colour(airmass, dark) == legend["night"], (_span_colour(airmass, dark), legend)
        assert _span_colour(airmass, dusk) == legend["twilight"], (_span_colour(airmass, dusk), legend)
    finally:
        plt.close(fig)
