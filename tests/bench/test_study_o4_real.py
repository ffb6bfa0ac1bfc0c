"""The ``o4-real`` recipe (issue 55 item 5): O4's real ranges, epochs, duty cycles and a FAR-like threshold.

The rewrite of a realised chunk runs on one of the committed chunks of the O4
population (``benchmarks/results/science/population_o4/previous_2026-12-06_o4_recipe/population/chunks``),
realised by ``bayestar-realize-coincs`` with H1, L1 and V1.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

CHUNKS = (Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "science" / "population_o4"
          / "previous_2026-12-06_o4_recipe" / "population" / "chunks")


def test_the_far_like_threshold_asks_more_of_a_single_detector():
    from mushrooms.evaluation.study.o4_real import FAR_THRESHOLD_HZ, far_like_hz, snr_threshold

    assert far_like_hz(8.0, 2) == pytest.approx(2.0 / 86400.0)  # the anchor: network SNR 8 <-> 2 per day
    assert snr_threshold(2) == pytest.approx(math.sqrt(64 + 2 * math.log(60.0)), rel=1e-9)  # 8.50: 2/day -> 1/month
    assert snr_threshold(1) == pytest.approx(snr_threshold(2) + 1.5)
    assert far_like_hz(snr_threshold(2), 3) == pytest.approx(FAR_THRESHOLD_HZ)
    assert far_like_hz(9.0, 1) > FAR_THRESHOLD_HZ > far_like_hz(9.0, 2)  # same SNR: coincident passes, single not
    assert far_like_hz(30.0, 0) == np.inf  # no trigger, no candidate


def test_o4_real_is_a_recipe_with_the_real_ranges_and_an_unchanged_o4_key():
    from mushrooms.evaluation.study import defaults
    from mushrooms.evaluation.study.recipes import O4_REAL_RANGES_MPC, O4_REAL_SOURCES, RECIPES, recipe_population

    assert "o4-real" in defaults.RECIPE_NAMES and tuple(RECIPES) == defaults.RECIPE_NAMES
    real, loc = recipe_population("o4-real", 15000, seed=2)
    o4, loc4 = recipe_population("o4", 15000, seed=2)
    assert real.post == "o4-real" and real.duty_cycle == 1.0 and loc == loc4
    assert real.key() != o4.key()
    committed = (CHUNKS.parent / "population.key").read_text().strip()
    assert o4.key() == committed  # adding the field `post` did not move the committed O4 population's key
    scale = {d: s for d, _, s in real.psd_scales}
    base = {d: s for d, _, s in o4.psd_scales}
    assert scale["H1"] / base["H1"] == pytest.approx(155 / 160, rel=1e-3)  # ranges scale with --X1-scale
    assert scale["V1"] / base["V1"] == pytest.approx(55 / 78, rel=1e-3)
    assert O4_REAL_RANGES_MPC == {"H1": 155.0, "L1": 160.0, "V1": 55.0}
    assert any("estimate" in s for s in O4_REAL_SOURCES)
    with pytest.raises(ValueError, match="post must be one of"):
        type(real)(post="o5")


def test_a_realised_chunk_as_o4_was(tmp_path):
    from ligo.skymap.io import events as gw_events

    from mushrooms.evaluation.study.o4_real import apply_o4_real, snr_threshold
    from mushrooms.evaluation.study.population import coinc_ids
    from mushrooms.evaluation.study.population_rows import coinc_injections

    kept_total = dropped_total = 0
    for k in range(6):
        src = CHUNKS / f"events-{k:04d}.xml.gz"
        before = coinc_ids(src)
        out = tmp_path / f"o4real-{k}.xml.gz"
        kept, dropped = apply_o4_real(str(src), 100 + k, str(out))
        assert kept + dropped == len(before) and coinc_ids(out) == sorted(set(coinc_ids(out)))
        assert set(coinc_ids(out)) <= set(before)
        truth = coinc_injections(out)
        assert set(truth) == set(coinc_ids(out))  # every kept candidate keeps its injection
        for cid, event in gw_events.open(str(out)).items():
            snrs = {s.detector: s.snr for s in event.singles}
            trig = [x for x in snrs.values() if x >= 4.0]
            assert math.sqrt(sum(x * x for x in trig)) >= snr_threshold(len(trig)) - 1e-9
        again = tmp_path / f"again-{k}.xml.gz"
        assert apply_o4_real(str(src), 100 + k, str(again)) == (kept, dropped)  # seeded
        assert coinc_ids(again) == coinc_ids(out)
        kept_total, dropped_total = kept_total + kept, dropped_total + dropped
    assert kept_total > 0 and dropped_total > 0  # duty cycles and the threshold remove some, not all


def test_an_epoch_without_virgo_removes_virgo_and_keeps_the_ligo_detectors_on(tmp_path, monkeypatch):
    from ligo.skymap.io import events as gw_events

    from mushrooms.evaluation.study import o4_real

    monkeypatch.setattr(o4_real, "O4_EPOCHS", (("O4a", 237.0, {"H1": 1.0, "L1": 1.0}),))
    src = CHUNKS / "events-0001.xml.gz"
    before = {c: {s.detector for s in e.singles} for c, e in gw_events.open(str(src)).items()}
    out = tmp_path / "o4a.xml.gz"
    o4_real.apply_o4_real(str(src), 1, str(out))
    after = {c: {s.detector for s in e.singles} for c, e in gw_events.open(str(out)).items()}
    assert any("V1" in d for d in before.values()) and after
    for cid, dets in after.items():
        assert dets == before[cid] - {"V1"}  # Virgo gone, both LIGO detectors kept (duty cycle 1)


def test_the_study_scores_a_simulated_coincidence_at_its_injected_truth(tmp_path):
    from mushrooms.evaluation.bench import BenchSettings
    from mushrooms.evaluation.study.graph import _with_truth
    from mushrooms.evaluation.study.localisation import MapTask
    from mushrooms.evaluation.study.population_rows import coinc_injections
    from mushrooms.scheduler_core.config import PlanningConfig

    settings = BenchSettings(config=PlanningConfig(solver="greedy", nside=64), solvers=("greedy",))
    events = str(CHUNKS / "events-0000.xml.gz")
    truth = coinc_injections(events)
    cid = sorted(truth)[0]
    got = _with_truth(settings, MapTask(key="k", name="n", path=str(tmp_path / "m.fits"), events=events, coinc_id=cid))
    assert got.truth == (truth[cid]["ra_deg"], truth[cid]["dec_deg"], truth[cid]["distance_mpc"])
    assert 0.0 <= got.truth[0] < 360.0 and -90.0 <= got.truth[1] <= 90.0 and got.truth[2] > 0
    plain = MapTask(key="k", name="n", path=str(tmp_path / "m.fits"))
    assert _with_truth(settings, plain).truth is None  # an existing map: its posterior
    missing = MapTask(key="k", name="n", path="x", events=str(tmp_path / "none.xml.gz"), coinc_id=0)
    assert _with_truth(settings, missing).truth is None  # its localisation task reports the missing file
