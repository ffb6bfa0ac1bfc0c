"""gwemopt-repaired: rule-breaking exposures dropped; the on-disk cache of raw gwemopt schedules."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from astropy.time import Time, TimeDelta

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scheduler"))
from conftest_milp import check_observations, tiny_config, tiny_problem  # noqa: E402
from mushrooms.evaluation.gwemopt_baseline import cache_key, repair_observations, run_gwemopt  # noqa: E402
from mushrooms.scheduler_core.plan.document import Observation  # noqa: E402

MAP = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "S200129m_cWB_RING.fits.gz"


def _o(fid, flt, t, exp=100.0):
    ra = {1: 0.0, 2: 5.0, 3: 10.0, 4: 15.0, 5: 20.0}[fid]
    return Observation(fid, ra, 0.0, flt, float(t), exp, 0)


def test_repair_drops_every_rule_breaking_exposure():
    problem = tiny_problem(tiny_config(cadence_s=250.0))
    obs = [
        _o(1, "g", 0.0), _o(2, "g", 105.0),       # field 2 starts only 5 s after field 1 ends: delayed to 108 s
        _o(3, "g", 150.0),                        # overlaps field 2's (delayed) exposure: dropped
        _o(1, "r", 400.0), _o(2, "r", 520.0),     # pairs for fields 1 and 2, >= 250 s after their g
        _o(4, "g", 700.0), _o(4, "r", 840.0),     # field 4: g and r only 140 s apart: unpaired
        _o(5, "g", 900.0), _o(5, "r", 3200.0),    # field 5 is not visible before 3000 s: g dropped, r unpaired
        _o(3, "i", 1200.0),                       # a filter the plan does not use
        _o(3, "g", 3550.0),                       # runs past the 1 h horizon
    ]
    fixed = repair_observations(obs, problem)
    kept = {(o.field_id, o.filter) for o in fixed.observations}
    assert kept == {(1, "g"), (2, "g"), (1, "r"), (2, "r")}
    assert check_observations(problem, fixed.observations) == []
    c = fixed.counts
    assert (c["delayed"], c["overlap"], c["unpaired"], c["window"], c["filter"], c["horizon"]) == (1, 1, 3, 1, 1, 1)
    # repairing again changes nothing
    again = repair_observations(fixed.observations, problem)
    assert again.observations == fixed.observations


def test_gwemopt_cache_is_keyed_on_map_and_options_and_read_back(tmp_path):
    cfg = tiny_config(nside=256, horizon_h=24.0)
    start = Time("2020-01-29T20:00:00", scale="utc")
    key = cache_key(MAP, start, cfg)
    assert key == cache_key(MAP, start, cfg)
    assert key != cache_key(MAP, Time("2020-01-29T21:00:00", scale="utc"), cfg)
    assert key != cache_key(MAP, start, tiny_config(nside=256, horizon_h=24.0, exposure_s=30.0))
    # a cached schedule is returned without any gwemopt interpreter
    mjd = start.mjd + 100.0 / 86400
    (tmp_path / f"{key}.dat").write_text(f"489 295.13032 4.55000 {mjd:.8f} 21.65 99 0.2 1.15 g\n")
    (tmp_path / f"{key}.json").write_text(json.dumps({"runtime_s": 91.5, "status": "ok"}))
    run = run_gwemopt(MAP, start, cfg, python="/nonexistent/python", cache_dir=tmp_path)
    assert run.status == "ok" and run.message == "cached" and run.runtime_s == 91.5
    assert [o.field_id for o in run.observations] == [489]
    assert run.observations[0].start == pytest.approx(100.0, abs=0.01)
    # a miss without an interpreter is 'unavailable' and writes nothing
    other = run_gwemopt(MAP, start + TimeDelta(3600, format="sec"), cfg, python="/nonexistent/python", cache_dir=tmp_path)
    assert other.status == "unavailable"
    assert len(list(tmp_path.iterdir())) == 2


def test_gwemopt_runs_with_one_thread_per_pool_unless_the_caller_chose():
    from mushrooms.evaluation.gwemopt_baseline import THREAD_CAPS, gwemopt_env

    env = gwemopt_env({"PATH": "/usr/bin", "OMP_NUM_THREADS": "3", "MPLBACKEND": "TkAgg"})
    assert env["OMP_NUM_THREADS"] == "3"
    assert env["RAYON_NUM_THREADS"] == "1" and env["NUMBA_NUM_THREADS"] == "1"
    assert all(name in env for name in THREAD_CAPS)
    assert env["MPLBACKEND"] == "Agg" and env["PATH"] == "/usr/bin"
