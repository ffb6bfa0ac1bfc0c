"""The checker rejects hand-broken plans, each for the right reason."""

from __future__ import annotations

import dataclasses

import pytest

from mushrooms.scheduler_core import check_plan
from mushrooms.scheduler_core.plan import sorted_observations


def _broken(plan, observations=None, **metrics):
    obs = sorted_observations(observations if observations is not None else plan.observations)
    m = dataclasses.replace(plan.metrics, **metrics) if metrics else plan.metrics
    return plan.with_(observations=obs, metrics=m)


def _kinds(report):
    return {line.split(":")[0] for line in report.problems}


def test_intact_plan_passes(greedy_plan, skymap_220722v, greedy_config):
    assert check_plan(greedy_plan, skymap_220722v, greedy_config).ok


def test_overlap_is_caught(greedy_plan, skymap_220722v, greedy_config):
    obs = list(greedy_plan.observations)
    obs[1] = dataclasses.replace(obs[1], start=obs[0].start + 100.0)
    report = check_plan(_broken(greedy_plan, obs), skymap_220722v, greedy_config)
    assert not report.ok and "overlap" in _kinds(report)


def test_too_short_slew_is_caught(greedy_plan, skymap_220722v, greedy_config):
    obs = list(greedy_plan.observations)
    obs[1] = dataclasses.replace(obs[1], start=obs[0].end + 2.0)  # less than the 8 s readout
    report = check_plan(_broken(greedy_plan, obs), skymap_220722v, greedy_config)
    assert "slew" in _kinds(report)


def test_out_of_window_is_caught(greedy_plan, skymap_220722v, greedy_config):
    obs = list(greedy_plan.observations)
    last = obs[-1]
    # move the last exposure to the middle of the next day: the Sun is up
    moved = dataclasses.replace(last, start=last.start + 12 * 3600.0)
    plan = _broken(greedy_plan, obs[:-1] + [moved])
    plan = plan.with_(end=plan.end + __import__("astropy.time").time.TimeDelta(14 * 3600, format="sec"))
    report = check_plan(plan, skymap_220722v, greedy_config)
    assert "window" in _kinds(report)
    assert any("Sun" in line for line in report.problems)


def test_cadence_violation_is_caught(greedy_plan, skymap_220722v, greedy_config):
    from dataclasses import replace

    cfg = replace(greedy_config, cadence_s=greedy_config.cadence_s * 3)  # same plan, stricter rule
    report = check_plan(greedy_plan, skymap_220722v, cfg)
    assert _kinds(report) == {"cadence"}


def test_missing_second_filter_is_caught(greedy_plan, skymap_220722v, greedy_config):
    obs = [o for o in greedy_plan.observations if not (o.field_id == greedy_plan.observations[0].field_id and o.filter == "r")]
    report = check_plan(_broken(greedy_plan, obs), skymap_220722v, greedy_config)
    assert any("not observed in both" in line for line in report.problems)


def test_outside_horizon_is_caught(greedy_plan, skymap_220722v, greedy_config):
    obs = list(greedy_plan.observations)
    obs[0] = dataclasses.replace(obs[0], start=-600.0)
    report = check_plan(_broken(greedy_plan, obs), skymap_220722v, greedy_config)
    assert "horizon" in _kinds(report)


def test_wrong_coverage_claim_is_caught(greedy_plan, skymap_220722v, greedy_config):
    report = check_plan(_broken(greedy_plan, coverage=greedy_plan.metrics.coverage + 0.05), skymap_220722v, greedy_config)
    assert _kinds(report) == {"coverage"}


def test_unknown_field_and_wrong_position_are_caught(greedy_plan, skymap_220722v, greedy_config):
    obs = list(greedy_plan.observations)
    obs[0] = dataclasses.replace(obs[0], field_id=99999)
    obs[2] = dataclasses.replace(obs[2], ra=obs[2].ra + 1.0)
    report = check_plan(_broken(greedy_plan, obs), skymap_220722v, greedy_config)
    assert any("unknown field 99999" in line for line in report.problems)
    assert any("not where the grid puts it" in line for line in report.problems)
