"""A population's results per (event, solver): events tied to their injections, the CSV, the papers' tables."""

from __future__ import annotations

import pytest

from mushrooms.evaluation.study.localisation import DEFAULT_EVENTS
from mushrooms.evaluation.study.population_rows import (POPULATION_COLUMNS, coinc_injections, population_events,
                                                        population_rows, read_population_csv,
                                                        source_frame_masses, write_population_csv)
from mushrooms.evaluation.study.population_tables import lumos_metric, paired_differences, population_tables
from mushrooms.evaluation.study.provenance import sha256_file


def test_each_coincidence_is_tied_to_the_injection_its_triggers_were_made_from():
    from ligo.skymap.io import events as gw_events

    injections = coinc_injections(DEFAULT_EVENTS)
    source = gw_events.open(str(DEFAULT_EVENTS))
    assert sorted(injections) == sorted(int(k) for k in source)
    for cid, inj in injections.items():
        template = source[cid].template_args
        assert (inj["mass1"], inj["mass2"], inj["spin1z"]) == pytest.approx(
            (template["mass1"], template["mass2"], template["spin1z"]))
    assert len({inj["distance_mpc"] for inj in injections.values()}) == len(injections)


def test_source_frame_masses_remove_the_redshift_of_the_luminosity_distance():
    from astropy import units as u
    from astropy.cosmology import Planck15, z_at_value

    d = [100.0, 450.0]
    m1, m2 = source_frame_masses([2.0, 2.0], [1.5, 1.5], d)
    for k, dist in enumerate(d):
        z = float(z_at_value(Planck15.luminosity_distance, dist * u.Mpc))
        assert m1[k] == pytest.approx(2.0 / (1 + z), rel=1e-4) and m2[k] == pytest.approx(1.5 / (1 + z), rel=1e-4)


def _records(events):
    """Study records of two solvers on every event (numbers made from the event's own distance); the hybrid
    rows carry the coverage as executed, the greedy rows were made before rows had it."""
    out = []
    for (sha, cid), ev in events.items():
        for solver, scale in (("greedy", 1.0), ("hybrid", 1.2)):
            cov = scale * 100.0 / ev["distance_mpc"]
            row = dict(coverage=cov, bound=cov * 1.5, efficiency_optimistic=cov / 2,
                       efficiency_conservative=cov / 3, efficiency_nsbh=cov / 4, valid=True,
                       runtime_s=0.5, n_exposures=40, area90_deg2=300.0, distmean_mpc=200.0, status="ok")
            if solver == "hybrid":
                row["coverage_as_executed"] = 0.75 * cov
            out.append(dict(map=f"{sha}:{cid}:opts", solver=solver, row=row))
    return out


def test_population_rows_name_each_event_by_chunk_and_coincidence_and_round_trip_the_csv(tmp_path):
    events = population_events([DEFAULT_EVENTS], prefix="o3")
    sha = sha256_file(DEFAULT_EVENTS)[:16]
    assert set(events) == {(sha, c) for c in range(21)}
    assert events[(sha, 7)]["event"] == "o3-0000-7" and {e["event_class"] for e in events.values()} == {"BNS"}
    records = _records(events)
    records.append(dict(map="0123456789abcdef:3:opts", solver="greedy", row=dict(coverage=0.9)))  # not an event
    for rec in records:
        rec["finished"] = "2026-12-05T22:00:00+00:00"
    # event 0 planned again by greedy under another configuration (other localisation options too): the later wins
    records.insert(0, dict(map=f"{sha}:0:other-opts", solver="greedy", finished="2026-12-05T23:00:00+00:00",
                           row=dict(coverage=0.123, valid=True)))
    rows = population_rows(records[::-1], events)
    assert [r["coverage"] for r in rows if r["event"] == "o3-0000-0" and r["solver"] == "greedy"] == [0.123]
    assert len(rows) == 42 and [r["event"] for r in rows[:4]] == ["o3-0000-0"] * 2 + ["o3-0000-1"] * 2
    assert all(r["coverage_executed"] == "" for r in rows if r["solver"] == "greedy")
    assert all(r["coverage_executed"] == pytest.approx(0.75 * r["coverage"]) for r in rows if r["solver"] == "hybrid")
    write_population_csv(rows, tmp_path / "results.csv")
    header = (tmp_path / "results.csv").read_text().splitlines()[0].split(",")
    assert tuple(header) == POPULATION_COLUMNS and header[:10] == [
        "event", "solver", "coverage", "coverage_executed", "upper_bound", "efficiency_optimistic",
        "efficiency_conservative", "efficiency_nsbh", "valid", "runtime_s"]
    back = read_population_csv(tmp_path / "results.csv")
    assert [(r["event"], r["solver"]) for r in back] == [(r["event"], r["solver"]) for r in rows]
    assert back[0]["coverage"] == pytest.approx(rows[0]["coverage"], abs=1e-6) and back[0]["valid"] is True
    for r in back:
        if r["solver"] == "greedy":
            assert r["coverage_executed"] is None
        else:
            assert r["coverage_executed"] == pytest.approx(0.75 * r["coverage"], abs=2e-6)


def _row(event, solver, cov, cls="BNS"):
    return dict(event=event, solver=solver, coverage=cov, upper_bound=1.0, efficiency_optimistic=cov / 2,
                efficiency_conservative=cov / 3, efficiency_nsbh=cov / 4, valid=True, runtime_s=1.0,
                event_class=cls, distance_mpc=100.0 * cov, area90_deg2=50.0 / cov, n_exposures=30)


def test_lumos_metric_is_the_ratio_of_mean_coverages_over_the_events_both_planned():
    from mushrooms.evaluation.study.population_tables import as_bench_rows

    rows = as_bench_rows([_row("a", "hybrid", 0.6), _row("b", "hybrid", 0.4), _row("c", "hybrid", 0.9),
                          _row("a", "gwemopt", 0.3), _row("b", "gwemopt", 0.2)])
    n, pct = lumos_metric(rows, "hybrid")
    assert n == 2 and pct == pytest.approx(100.0 * ((0.6 + 0.4) / (0.3 + 0.2) - 1))
    assert lumos_metric(rows, "greedy") == (0, None)


def test_population_tables_pair_ours_with_every_baseline_and_split_by_class():
    from mushrooms.evaluation.study.population_tables import as_bench_rows

    rows = []
    for k, (cls, cov) in enumerate([("BNS", 0.5), ("BNS", 0.3), ("NSBH", 0.2), ("NSBH", 0.6)]):
        rows += [_row(f"e{k}", "greedy", cov, cls), _row(f"e{k}", "hybrid", cov + 0.1, cls),
                 _row(f"e{k}", "gwemopt", cov + 0.05, cls)]
    lines = paired_differences(as_bench_rows(rows), ["hybrid", "greedy"])
    assert any(line.startswith("| hybrid − greedy | 4 | +0.1000 ± 0.0000 (4/0)") for line in lines)
    assert any(line.startswith("| hybrid − gwemopt | 4 | +0.0500") for line in lines)
    assert any(line.startswith("| greedy − gwemopt | 4 | -0.0500") for line in lines)
    rows[1]["status"] = "not_observable"  # e0's hybrid row: the service's answer below min_coverage
    text = population_tables(rows + [_row("late", "greedy", 0.9)])  # an event greedy alone has planned yet
    executed = text.split("## Planned and executed coverage")[1].splitlines()
    assert next(x for x in executed if x.startswith("| hybrid |")).endswith("| - | - | - | 4 | 1 |")
    assert next(x for x in executed if x.startswith("| greedy |")).endswith("| 4 | 0 |")
    assert text.startswith("4 events with every solver's row (of 5), 12 (event, solver) rows")
    mean_gw = sum(c + 0.05 for c in (0.5, 0.3, 0.2, 0.6)) / 4
    mean_hy = sum(c + 0.1 for c in (0.5, 0.3, 0.2, 0.6)) / 4
    assert f"- hybrid: {100 * (mean_hy / mean_gw - 1):+.1f} % (bootstrap 68 %: " in text
    assert ") over 4 events\n" in text  # (no executed coverage in these rows: the planned one alone)
    assert "| BNS | 2 |" in text and "| NSBH | 2 |" in text
    assert "coverage_executed (as ZTF would execute the queues) filled on 0" in text
    assert "best(hybrid,gwemopt)" in text  # the paper's hybrid row of Tables 2-3


def test_population_figures_pair_ours_with_each_baseline_over_the_complete_events(tmp_path):
    from PIL import Image

    from mushrooms.evaluation.study.population_figures import population_figures

    rows = []
    for k, (cls, cov) in enumerate([("BNS", 0.5), ("BNS", 0.3), ("NSBH", 0.2), ("NSBH", 0.6)]):
        for solver, extra in (("greedy", 0.0), ("service", 0.1), ("gwemopt", 0.05), ("gwemopt-repaired", -0.1)):
            r = _row(f"e{k}", solver, cov + extra, cls)
            r["coverage_executed"] = 0.8 * r["coverage"]
            rows.append(r)
    written = population_figures(rows + [_row("late", "greedy", 0.9)], tmp_path)
    assert sorted(p.name for p in written) == ["paired_by_distance_area.png", "population.png"]
    paired, population = (Image.open(tmp_path / f"{n}.png") for n in ("paired_by_distance_area", "population"))
    assert paired.size[1] > population.size[1]  # one row of panels per baseline
    assert population_figures([_row("late", "greedy", 0.9)], tmp_path / "one") == written[:0] + [
        tmp_path / "one" / "population.png"]  # one solver: no baseline to pair with


def test_lumos_interval_is_the_spread_of_the_metric_over_resampled_events():
    from mushrooms.evaluation.study.population_tables import as_bench_rows, lumos_interval

    same = as_bench_rows([_row(e, s, c * (1.5 if s == "service" else 1.0))
                          for e, c in (("a", 0.2), ("b", 0.4), ("c", 0.6)) for s in ("service", "gwemopt")])
    lo, hi = lumos_interval(same, "service")  # every event 50 % better: so is every resample
    assert lo == pytest.approx(50.0) and hi == pytest.approx(50.0)
    mixed = as_bench_rows([_row("a", "service", 0.6), _row("a", "gwemopt", 0.2),
                           _row("b", "service", 0.2), _row("b", "gwemopt", 0.4)])
    lo, hi = lumos_interval(mixed, "service")
    n, pct = lumos_metric(mixed, "service")
    assert lo < pct < hi and lo >= -50.0 and hi <= 200.0  # between the two events' own ratios
    assert lumos_interval(mixed[:2], "service") is None  # one event: no spread to measure
