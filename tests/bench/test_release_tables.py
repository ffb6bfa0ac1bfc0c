"""The release's tables from a population CSV (issue 55): medians and bootstrap intervals beside means, per-event
paired differences against the service, events each row executes nothing on, by class, distance and area."""

from __future__ import annotations

import numpy as np
import pytest

from mushrooms.evaluation.study.population_rows import (POPULATION_COLUMNS, population_row, read_population_csv,
                                                        write_population_csv)

#: Executed coverage (queue set) per event and row: e4 is an event gwemopt-o4 executes nothing on.
EXECUTED = {
    "service": [0.50, 0.40, 0.30, 0.20, 0.10],
    "greedy": [0.45, 0.41, 0.25, 0.20, 0.05],
    "gwemopt-o4": [0.30, 0.0, 0.10, 0.0, 0.05],
}
CLASSES = ["BNS", "BNS", "NSBH", "BNS", "NSBH"]
DISTANCES = [100.0, 200.0, 300.0, 400.0, 500.0]


def _rows():
    rows = []
    for solver, values in EXECUTED.items():
        for k, v in enumerate(values):
            today = 0.0 if solver == "gwemopt-o4" else v * 0.9
            rows.append(dict(event=f"e{k}", solver=solver, coverage=v + 0.05, coverage_executed=v,
                             coverage_executed_single_queue=today, coverage_pairs=v + 0.01, valid=solver != "gwemopt-o4",
                             efficiency_optimistic=v / 10, efficiency_two_detections="",
                             open_shutter_s=3600.0 * (k + 1), event_class=CLASSES[k], distance_mpc=DISTANCES[k],
                             area90_deg2=100.0 * (5 - k), commit="abc1234", status="ok"))
    rows.append(dict(event="e5", solver="service", coverage=0.2, coverage_executed=0.2, commit="abc1234"))  # partial
    return rows


@pytest.fixture()
def csv_rows(tmp_path):
    path = tmp_path / "results.csv"
    write_population_csv(_rows(), path)
    return read_population_csv(path)


def test_the_population_csv_carries_the_release_columns_and_the_commit(tmp_path):
    for column in ("coverage_executed_single_queue", "efficiency_two_detections", "commit", "open_shutter_s",
                   "coverage_pairs"):
        assert column in POPULATION_COLUMNS
    bench_row = dict(solver="gwemopt-o4", coverage=0.3, coverage_as_executed=0.2, coverage_single_queue=0.1,
                     coverage_pairs=0.25, open_shutter_s=5400.0, open_shutter_executed_s=3600.0, n_problems=12,
                     commit="deadbeef", valid=False)
    row = population_row(bench_row, dict(event="o4-0001-2", event_class="NSBH", distance_mpc=210.0))
    assert (row["coverage_executed"], row["coverage_executed_single_queue"], row["coverage_pairs"]) == (0.2, 0.1, 0.25)
    assert (row["open_shutter_s"], row["commit"], row["event_class"]) == (5400.0, "deadbeef", "NSBH")
    path = tmp_path / "r.csv"
    write_population_csv([row], path)
    back = read_population_csv(path)[0]
    assert back["commit"] == "deadbeef" and back["coverage_executed_single_queue"] == 0.1
    assert population_row({**bench_row, "commit": ""}, dict(event="x", event_class="BNS", distance_mpc=1.0),
                          commit="cafe")["commit"] == "cafe"


def test_bootstrap_intervals_are_seeded_percentiles_of_resampled_events():
    from mushrooms.evaluation.study.release_tables import bootstrap_interval, summary

    x = [0.1, 0.4, 0.2, 0.9, 0.3, 0.5]
    a = bootstrap_interval(x, np.mean, draws=500, seed=3)
    assert a == bootstrap_interval(x, np.mean, draws=500, seed=3)
    pick = np.random.default_rng(3).integers(0, 6, size=(500, 6))
    expected = np.percentile(np.asarray(x)[pick].mean(axis=1), [2.5, 97.5])
    assert a == pytest.approx(tuple(expected), abs=1e-12)
    assert a[0] < np.mean(x) < a[1]
    assert bootstrap_interval([0.2] * 5, np.median) == (0.2, 0.2)
    assert bootstrap_interval([0.2]) is None
    s = summary(x, draws=500, seed=3)
    assert (s["n"], s["mean"], s["median"]) == (6, pytest.approx(0.4), pytest.approx(0.35))
    assert s["median_ci"][0] <= 0.35 <= s["median_ci"][1]


def test_paired_differences_and_zero_execution_counts_per_row(csv_rows):
    from mushrooms.evaluation.study.release_tables import (metric_values, paired_differences, release_events,
                                                           zero_counts)

    rows = release_events(csv_rows)
    assert {r["event"] for r in rows} == {"e0", "e1", "e2", "e3", "e4"}  # e5 has the service's row alone
    d = paired_differences(rows, "gwemopt-o4", "coverage_executed")
    assert d == pytest.approx({f"e{k}": EXECUTED["gwemopt-o4"][k] - EXECUTED["service"][k] for k in range(5)})
    assert metric_values(rows, "greedy", "open_shutter_s", 1 / 3600) == pytest.approx({f"e{k}": k + 1.0 for k in range(5)})
    assert zero_counts(rows, "gwemopt-o4") == dict(events=5, planned=0, queue_set=2, single_queue=5, valid=0)
    assert zero_counts(rows, "service") == dict(events=5, planned=0, queue_set=0, single_queue=0, valid=5)


def test_the_tables_show_medians_intervals_differences_zero_events_and_the_breakdowns(csv_rows):
    from mushrooms.evaluation.study.release_tables import release_tables

    text = release_tables(csv_rows, draws=400, seed=1)
    assert text == release_tables(csv_rows, draws=400, seed=1)
    assert text.startswith("5 events with a row of every row name (of 6); 15 (event, row) rows; planned by "
                           "`abc1234` (15 rows).")
    lines = text.splitlines()
    row = next(ln for ln in lines if ln.startswith("| gwemopt-o4 | 5 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    # executed via queue set: mean 0.090, median 0.050
    assert cells[3].startswith("0.090 [") and " / 0.050 [" in cells[3]
    diff = next(ln for ln in lines if ln.startswith("| gwemopt-o4 | ") and "(0/5/0 of 5)" in ln)
    mean = np.mean(np.array(EXECUTED["gwemopt-o4"]) - np.array(EXECUTED["service"]))
    assert f"{mean:+.3f} [" in diff
    assert "| gwemopt-o4 | 5 | 0 | 2 | 5 | 0 |" in lines
    assert "| greedy | 5 | 0 | 0 | 0 | 5 |" in lines
    by_class = lines[lines.index("## By event_class") + 4:]
    assert by_class[0].startswith("| BNS | 3 |") and by_class[1].startswith("| NSBH | 2 |")
    bns = [c.strip() for c in by_class[0].strip("|").split("|")]
    assert bns[2:] == ["0.400 / 0.360 (0)", "0.410 / 0.369 (0)", "0.000 / 0.000 (2)"]
    assert "## By distance_mpc (quartiles over the events)" in text and "| Q4 (> 400) | 1 |" in text
