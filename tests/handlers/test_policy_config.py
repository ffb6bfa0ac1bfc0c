"""The [policy] table and its verdict on real notices."""

from __future__ import annotations

import dataclasses
from datetime import datetime, timedelta, timezone

import pytest

from mushrooms.tool.config import Config, ConfigError
from mushrooms.handlers.alert import parse_notice
from mushrooms.handlers.policy import PolicyConfig, evaluate, superevent_kind

from notice_helpers import dumps, notice_bytes, notice_dict

MOCK = PolicyConfig(allow_mock=True)


def at(alert, minutes=1.0):
    """Receipt time a little after the notice was created."""
    return alert.time_created + timedelta(minutes=minutes)


def alert(rel="json/MS181101ab-preliminary.json", **event):
    d = notice_dict(rel)
    d["event"].update(event) if event else None
    return parse_notice(dumps(d))


# ------------------------------------------------------------------ configuration

def test_defaults_and_docstring_list_every_key():
    doc = PolicyConfig.__doc__
    for f in dataclasses.fields(PolicyConfig):
        assert f"{f.name} :" in doc, f.name
    assert PolicyConfig().allow_mock is False
    assert PolicyConfig().groups == ("CBC",)


def test_from_mapping_rejects_unknown_keys_and_bad_values():
    with pytest.raises(ValueError, match="unknown \\[policy\\] key\\(s\\): min_bns"):
        PolicyConfig.from_mapping({"min_bns": 0.5})
    with pytest.raises(ValueError, match="probability"):
        PolicyConfig.from_mapping({"min_has_ns": 2})
    with pytest.raises(ValueError, match="plan_start"):
        PolicyConfig.from_mapping({"plan_start": "tomorrow"})
    with pytest.raises(ValueError, match="unknown alert type"):
        PolicyConfig.from_mapping({"alert_types": ["FINAL"]})
    with pytest.raises(ValueError, match=r"\[policy\] allow_mock = 'yes': expected a boolean, got string"):
        PolicyConfig.from_mapping({"allow_mock": "yes"})


def test_from_mapping_turns_lists_into_tuples_and_config_reads_the_table():
    cfg = Config.from_mapping({"policy": {"groups": ["CBC", "Burst"], "allow_mock": True,
                                          "max_notice_age_s": 0}})
    assert cfg.policy.groups == ("CBC", "Burst")
    assert cfg.policy.allow_mock is True
    with pytest.raises(ConfigError, match="policy"):
        Config.from_mapping({"policy": {"nope": 1}})


# ------------------------------------------------------------------ verdicts

def test_mock_events_need_allow_mock():
    a = alert()
    v = evaluate(a, PolicyConfig(), at(a))
    assert not v.keep and "mock" in v.reason
    v = evaluate(a, MOCK, at(a))
    assert v.keep and "P(BNS)+P(NSBH) 0.960" in v.reason


def test_prefixes():
    assert superevent_kind("S230528ay") == "real"
    assert superevent_kind("MS181101ab") == "mock"
    assert superevent_kind("TS230101a") == "test"
    assert superevent_kind("GW170817") == "unknown"
    d = notice_dict("json/MS181101ab-preliminary.json")
    d["superevent_id"] = "TS181101ab"
    a = parse_notice(dumps(d))
    assert not evaluate(a, PolicyConfig(), at(a)).keep
    assert evaluate(a, MOCK, at(a)).keep
    d["superevent_id"] = "S181101ab"  # a real event passes with the defaults
    a = parse_notice(dumps(d))
    assert evaluate(a, PolicyConfig(), at(a)).keep


def test_real_burst_event_is_ignored_with_reason():
    a = parse_notice(notice_bytes("live/S230528ay-preliminary.json"))
    v = evaluate(a, PolicyConfig(), at(a))
    assert not v.keep and v.reason == "group Burst not in CBC"
    # even with Burst allowed, it is not significant
    v = evaluate(a, PolicyConfig(groups=("CBC", "Burst")), at(a))
    assert not v.keep and v.reason.startswith("not significant: a low-significance alert")


def test_bbh_dominated_event_is_ignored():
    a = alert(classification={"BNS": 0.0, "NSBH": 0.02, "BBH": 0.97, "Terrestrial": 0.01},
              properties={"HasNS": 0.01, "HasRemnant": 0.0})
    v = evaluate(a, MOCK, at(a))
    assert not v.keep
    assert "no neutron star" in v.reason and "most likely BBH 0.970" in v.reason


def test_has_ns_alone_is_enough():
    a = alert(classification={"BNS": 0.0, "NSBH": 0.05, "BBH": 0.9, "Terrestrial": 0.05},
              properties={"HasNS": 0.8})
    v = evaluate(a, MOCK, at(a))
    assert v.keep and v.reason.startswith("HasNS 0.800")
    assert not evaluate(a, dataclasses.replace(MOCK, min_has_ns=0.9), at(a)).keep


def test_far_and_significance_cuts():
    a = alert(far=1e-5)
    v = evaluate(a, MOCK, at(a))
    assert not v.keep and "FAR 1e-05 Hz above max_far_hz" in v.reason
    assert evaluate(a, dataclasses.replace(MOCK, max_far_hz=0), at(a)).keep
    b = alert(significant=False)
    assert evaluate(b, MOCK, at(b)).reason.startswith("not significant:")
    assert evaluate(b, dataclasses.replace(MOCK, require_significant=False), at(b)).keep


def test_age_limits():
    a = alert()
    v = evaluate(a, MOCK, at(a, minutes=120))
    assert not v.keep and "notice is 7200 s old" in v.reason
    assert evaluate(a, dataclasses.replace(MOCK, max_notice_age_s=0), at(a, minutes=120)).keep
    late = dataclasses.replace(MOCK, max_notice_age_s=0, max_event_age_s=3600)
    v = evaluate(a, late, a.event.time + timedelta(hours=2))
    assert not v.keep and "event is 7200 s old" in v.reason
    # archived notices are years old on the wall clock
    assert not evaluate(a, MOCK, datetime.now(timezone.utc)).keep


def test_retraction_passes_source_cuts_but_not_the_prefix():
    r = parse_notice(notice_bytes("json/MS181101ab-retraction.json"))
    assert evaluate(r, MOCK, at(r)).keep
    assert not evaluate(r, PolicyConfig(), at(r)).keep


def test_alert_type_filter():
    ew = parse_notice(notice_bytes("json/MS181101ab-earlywarning.json"))
    no_ew = dataclasses.replace(MOCK, alert_types=("PRELIMINARY", "INITIAL", "UPDATE"))
    assert "not in policy alert_types" in evaluate(ew, no_ew, at(ew)).reason
    old_spelling = dataclasses.replace(MOCK, alert_types=("EARLY_WARNING",))
    assert evaluate(ew, old_spelling, at(ew)).keep
