"""Planning on the joint GW x external localisation: choice, fallback, decisions."""

from __future__ import annotations

import base64
import hashlib
from datetime import timedelta

import pytest

from mushrooms.handlers.alert import parse_notice
from mushrooms.handlers.decisions import MemoryLedger, decide
from mushrooms.handlers.localization import (COMBINED, GW, check_skymap, choose_localization,
                                             coincidence_summary, skymap_for_sha)
from mushrooms.handlers.policy import PolicyConfig, evaluate
from mushrooms.scheduler_core import SkyMapError

from notice_helpers import dumps, notice_bytes, notice_dict

EXT = "json/MS181101ab-ext-update.json"
POLICY = PolicyConfig(allow_mock=True)


def combined_bytes(rel: str = EXT) -> bytes:
    return base64.b64decode(notice_dict(rel)["external_coinc"]["combined_skymap"])


def with_combined(data: bytes, rel: str = EXT) -> object:
    """The ext-update notice carrying other combined-map bytes."""
    d = notice_dict(rel)
    d["external_coinc"]["combined_skymap"] = base64.b64encode(data).decode()
    return parse_notice(dumps(d))


@pytest.mark.parametrize("rel", [EXT, "avro/MS181101ab-ext-update.avro"])
def test_the_joint_map_is_chosen_when_present_and_valid(rel):
    alert = parse_notice(notice_bytes(rel))
    loc = choose_localization(alert, use_combined=True)
    assert loc.kind == COMBINED
    assert loc.sha256 == alert.external_coinc.combined_skymap_sha256 == hashlib.sha256(loc.skymap).hexdigest()
    assert loc.sha256 != alert.skymap_sha256  # the joint map really is another map
    assert loc.sha256.startswith("1e087b1837bd")
    assert "Fermi" in loc.note


def test_the_policy_can_keep_the_gw_map():
    alert = parse_notice(notice_bytes(EXT))
    loc = choose_localization(alert, use_combined=False)
    assert loc.kind == GW and loc.sha256 == alert.skymap_sha256 and loc.skymap == alert.skymap
    assert "use_combined_skymap=false" in loc.note and not loc.joint_preferred


def test_a_gw_only_notice_plans_the_gw_map():
    alert = parse_notice(notice_bytes("json/MS181101ab-update.json"))
    loc = choose_localization(alert, use_combined=True)
    assert (loc.kind, loc.sha256, loc.note) == (GW, alert.skymap_sha256, "")
    assert choose_localization(parse_notice(notice_bytes("json/MS181101ab-retraction.json")), True) is None


@pytest.mark.parametrize("bad", [
    b"SIMPLE  =                    T" + b" " * 50,           # a FITS card and nothing else
    combined_bytes()[:20000],                                 # truncated
    b"\x1f\x8b" + b"not really gzip at all",                 # broken gzip
])
def test_an_unusable_joint_map_falls_back_to_the_gw_map_with_the_reason(bad):
    alert = with_combined(bad)
    with pytest.raises(SkyMapError):
        check_skymap(bad)
    loc = choose_localization(alert, use_combined=True)
    assert loc.kind == GW and loc.sha256 == alert.skymap_sha256
    assert "combined sky map unusable" in loc.note and "SkyMapError" in loc.note


def test_a_joint_map_that_breaks_the_reader_in_any_way_still_falls_back():
    def broken_reader(data):
        raise OSError("disk on fire")

    loc = choose_localization(parse_notice(notice_bytes(EXT)), True, check=broken_reader)
    assert loc.kind == GW and "OSError: disk on fire" in loc.note


def test_skymap_for_sha_finds_either_map_and_nothing_else():
    alert = parse_notice(notice_bytes(EXT))
    assert skymap_for_sha(alert, alert.external_coinc.combined_skymap_sha256) == (COMBINED, combined_bytes())
    assert skymap_for_sha(alert, alert.skymap_sha256) == (GW, alert.skymap)
    assert skymap_for_sha(alert, "0" * 64) is None


def test_the_coincidence_summary_carries_observatory_search_and_fars():
    s = coincidence_summary(parse_notice(notice_bytes(EXT)).external_coinc)
    d = notice_dict(EXT)["external_coinc"]
    assert s["observatory"] == "Fermi" and s["search"] == "GRB"
    assert s["time_difference_s"] == pytest.approx(2.02)
    assert s["time_sky_position_coincidence_far_hz"] == pytest.approx(d["time_sky_position_coincidence_far"])
    assert s["time_coincidence_far_hz"] == pytest.approx(d["time_coincidence_far"])
    assert "combined_skymap" not in s  # no map bytes in a plan document
    assert coincidence_summary(None) is None


def run(alerts, use_combined=True):
    """Decide each alert in order as the service does, applying each decision to a ledger."""
    ledger = MemoryLedger()
    out = []
    for i, a in enumerate(alerts):
        a = parse_notice(notice_bytes(a)) if isinstance(a, str) else a
        loc = None if a.is_retraction else choose_localization(a, use_combined)
        d = decide(a, evaluate(a, POLICY, a.time_created + timedelta(seconds=5)), ledger, loc)
        ledger.apply(d, plan_id=f"plan-{i}" if d.needs_plan else None)
        out.append(d)
    return out, ledger


def test_the_coincidence_update_supersedes_onto_the_joint_map_and_a_gw_only_update_keeps_it():
    seq = ["json/MS181101ab-earlywarning.json", "json/MS181101ab-preliminary.json", EXT,
           "json/MS181101ab-update.json", "json/MS181101ab-retraction.json"]
    out, ledger = run(seq)
    assert [d.action for d in out] == ["plan", "duplicate", "rerun", "duplicate", "withdraw"]
    gw_sha = parse_notice(notice_bytes(seq[0])).skymap_sha256
    joint_sha = parse_notice(notice_bytes(EXT)).external_coinc.combined_skymap_sha256
    assert (out[0].localization, out[0].skymap_sha256) == (GW, gw_sha)
    assert (out[2].localization, out[2].skymap_sha256, out[2].supersedes) == (COMBINED, joint_sha, "plan-0")
    # the later GW-only UPDATE (same GW map, no coincidence) does not drop the joint map, and says so
    assert out[3].skymap_sha256 == joint_sha and out[3].plan_ids == ("plan-0", "plan-2")
    assert "keeping the joint localisation" in out[3].reason
    assert out[4].plan_ids == ("plan-0", "plan-2")  # the retraction withdraws both
    assert ledger.event_state("MS181101ab").retracted


def test_a_new_joint_map_is_a_new_sky_map():
    # another valid map as the joint map: the GW map of the live MS230425k
    other = base64.b64decode(notice_dict("live/MS230425k-preliminary.json")["event"]["skymap"])
    out, _ = run([EXT, with_combined(other)])
    assert [d.action for d in out] == ["plan", "rerun"]
    assert out[1].localization == COMBINED and out[1].skymap_sha256 == hashlib.sha256(other).hexdigest()
    assert out[1].supersedes == "plan-0"


def test_a_broken_joint_map_after_a_joint_plan_keeps_the_joint_plan():
    out, _ = run([EXT, with_combined(b"SIMPLE  = garbage")])
    assert [d.action for d in out] == ["plan", "duplicate"]
    assert "keeping the joint localisation" in out[1].reason and "unusable" in out[1].reason


def test_with_the_policy_off_a_joint_plan_gives_way_to_the_gw_map():
    ledger = MemoryLedger()
    a = parse_notice(notice_bytes(EXT))
    first = decide(a, evaluate(a, POLICY, a.time_created), ledger, choose_localization(a, True))
    ledger.apply(first, plan_id="plan-0")
    b = parse_notice(notice_bytes("json/MS181101ab-update.json"))
    d = decide(b, evaluate(b, POLICY, b.time_created), ledger, choose_localization(b, False))
    assert first.localization == COMBINED
    assert d.action == "rerun" and d.localization == GW and d.skymap_sha256 == b.skymap_sha256
