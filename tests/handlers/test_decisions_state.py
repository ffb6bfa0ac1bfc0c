"""Per-superevent decisions on sequences of real notices."""

from __future__ import annotations

import base64
from datetime import timedelta

from mushrooms.handlers.alert import parse_notice
from mushrooms.handlers.decisions import Decision, EventState, MemoryLedger, decide
from mushrooms.handlers.policy import PolicyConfig, Verdict, evaluate

from notice_helpers import dumps, notice_bytes, notice_dict

POLICY = PolicyConfig(allow_mock=True)


def run(rels_or_alerts, ledger=None):
    """Decide each notice in order, applying each decision like the store does."""
    ledger = ledger or MemoryLedger()
    out = []
    for i, item in enumerate(rels_or_alerts):
        a = parse_notice(notice_bytes(item)) if isinstance(item, str) else item
        d = decide(a, evaluate(a, POLICY, a.time_created + timedelta(seconds=5)), ledger)
        ledger.apply(d, plan_id=f"plan-{i}" if d.needs_plan else None)
        out.append(d)
    return out, ledger


def with_map_of(rel_target: str, rel_map: str) -> object:
    """``rel_target`` carrying the sky map of ``rel_map`` (both real notices)."""
    d = notice_dict(rel_target)
    d["event"]["skymap"] = notice_dict(rel_map)["event"]["skymap"]
    return parse_notice(dumps(d))


def test_lvk_user_guide_sequence():
    seq = ["json/MS181101ab-earlywarning.json", "json/MS181101ab-preliminary.json",
           "json/MS181101ab-preliminary.json",  # LVK sends two PRELIMINARY notices
           "json/MS181101ab-initial.json", "json/MS181101ab-update.json", "json/MS181101ab-retraction.json"]
    out, ledger = run(seq)
    assert [d.action for d in out] == ["plan", "duplicate", "duplicate", "duplicate", "duplicate", "withdraw"]
    assert out[1].plan_ids == ("plan-0",)
    assert out[-1].plan_ids == ("plan-0",)
    assert ledger.event_state("MS181101ab").retracted


def test_changed_sky_map_is_a_rerun_that_supersedes():
    changed = with_map_of("json/MS181101ab-update.json", "live/MS230425k-preliminary.json")
    out, _ = run(["json/MS181101ab-preliminary.json", changed])
    assert [d.action for d in out] == ["plan", "rerun"]
    assert out[1].supersedes == "plan-0"
    assert out[1].skymap_sha256 == changed.skymap_sha256 != out[0].skymap_sha256
    assert "sky map changed" in out[1].reason


def test_retraction_then_later_initial_plans_again():
    out, ledger = run(["live/MS230425k-preliminary.json", "live/MS230425k-retraction.json",
                       "live/MS230425k-initial.json"])
    assert [d.action for d in out] == ["plan", "withdraw", "plan"]
    assert "after a retraction" in out[2].reason
    assert out[2].supersedes is None
    assert ledger.event_state("MS230425k") == EventState("MS230425k", out[2].skymap_sha256, ("plan-2",), False, "gw",
                                                         latest_created=out[2].time_created)


def test_retractions_of_unknown_or_retracted_events_are_ignored():
    out, _ = run(["live/MS230425k-retraction.json"])
    assert out[0].action == "ignore" and "never planned" in out[0].reason
    out, _ = run(["live/MS230425k-preliminary.json", "live/MS230425k-retraction.json",
                  "live/MS230425k-retraction.json"])
    assert [d.action for d in out] == ["plan", "withdraw", "ignore"]


def test_policy_refusal_is_ignore_whatever_the_state():
    a = parse_notice(notice_bytes("live/S230528ay-preliminary.json"))
    d = decide(a, Verdict(False, "group Burst not in CBC"), MemoryLedger())
    assert d == Decision("ignore", "S230528ay", "group Burst not in CBC", "PRELIMINARY",
                         time_created="2023-05-28T11:40:43.000Z")


def test_superevents_are_independent():
    out, _ = run(["json/MS181101ab-preliminary.json", "live/MS230425k-preliminary.json",
                  "json/MS181101ab-initial.json"])
    assert [d.action for d in out] == ["plan", "plan", "duplicate"]


def test_failed_planning_is_retried_with_the_same_map():
    a = parse_notice(notice_bytes("json/MS181101ab-initial.json"))
    ledger = MemoryLedger({"MS181101ab": EventState("MS181101ab", None, (), False)})
    d = decide(a, Verdict(True, "ok"), ledger)
    assert d.action == "plan" and "planning again" in d.reason
    assert base64.b64decode(notice_dict("json/MS181101ab-initial.json")["event"]["skymap"])[:6] == b"SIMPLE"
