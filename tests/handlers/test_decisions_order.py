"""Creation order, not arrival order: a stale notice never supersedes a newer one."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

from mushrooms.handlers.alert import parse_notice
from mushrooms.handlers.decisions import MemoryLedger, decide, newest_created
from mushrooms.handlers.policy import PolicyConfig, evaluate

from notice_helpers import dumps, notice_dict

POLICY = PolicyConfig(allow_mock=True, max_notice_age_s=0, max_event_age_s=0)


def notice(rel: str, shift_s: float = 0.0, map_of: str | None = None):
    """A real notice with its ``time_created`` moved by ``shift_s`` (s) and maybe another one's sky map."""
    d = notice_dict(rel)
    t = datetime.fromisoformat(d["time_created"].replace("Z", "+00:00")) + timedelta(seconds=shift_s)
    d["time_created"] = t.strftime("%Y-%m-%dT%H:%M:%SZ")
    if map_of is not None:
        d["event"]["skymap"] = notice_dict(map_of)["event"]["skymap"]
    return parse_notice(dumps(d))


def run(alerts, ledger=None):
    ledger = ledger or MemoryLedger()
    out = []
    for i, a in enumerate(alerts):
        d = decide(a, evaluate(a, POLICY, datetime(2030, 1, 1, tzinfo=timezone.utc)), ledger)
        ledger.apply(d, plan_id=f"plan-{i}" if d.needs_plan else None)
        out.append(d)
    return out, ledger


PRE, RET, INI = ("live/MS230425k-preliminary.json", "live/MS230425k-retraction.json",
                 "live/MS230425k-initial.json")


def test_a_late_preliminary_created_before_the_retraction_does_not_reopen_the_event():
    # RETRACTION, then a PRELIMINARY created 300 s before it that arrives late
    ret = notice(RET)
    late = notice(PRE, shift_s=(datetime(2023, 4, 25, 11, 2, 9) - datetime(2023, 4, 25, 10, 56, 53)).total_seconds()
                  - 300)
    out, ledger = run([notice(PRE), ret, late])
    assert [d.action for d in out] == ["plan", "withdraw", "ignore"]
    assert "before the retraction" in out[2].reason and "stale" in out[2].reason
    assert ledger.event_state("MS230425k").retracted


def test_an_initial_created_before_the_retraction_is_stale_but_a_later_one_reopens():
    early_initial = notice(INI, shift_s=-(datetime(2023, 4, 25, 12, 19, 40)
                                          - datetime(2023, 4, 25, 11, 0, 0)).total_seconds())
    out, _ = run([notice(PRE), notice(RET), early_initial, notice(INI)])
    assert [d.action for d in out] == ["plan", "withdraw", "ignore", "plan"]
    assert "after a retraction" in out[3].reason


def test_an_older_preliminary_with_another_map_never_supersedes_the_newer_update():
    update = notice("json/MS181101ab-update.json", map_of="live/MS230425k-preliminary.json")
    older = notice("json/MS181101ab-preliminary.json")  # created 96 s before the update, other map
    out, ledger = run([update, older])
    assert [d.action for d in out] == ["plan", "ignore"]
    assert "never supersedes" in out[1].reason
    assert ledger.event_state("MS181101ab").skymap_sha256 == update.skymap_sha256


def test_an_earlywarning_created_before_the_preliminary_arriving_after_it_is_stale():
    ew = notice("json/MS181101ab-earlywarning.json", map_of="live/MS230425k-preliminary.json")
    out, _ = run([notice("json/MS181101ab-preliminary.json"), ew])
    assert [d.action for d in out] == ["plan", "ignore"]


def test_a_stale_retraction_does_not_withdraw_a_newer_plan():
    # LVK retracted, then re-opened the event with a later INITIAL; the retraction arrives last
    out, ledger = run([notice(PRE), notice(INI, map_of="json/MS181101ab-preliminary.json"), notice(RET)])
    assert [d.action for d in out] == ["plan", "rerun", "ignore"]
    assert not ledger.event_state("MS230425k").retracted


def test_same_creation_time_and_newer_notices_keep_working():
    out, ledger = run([notice(PRE), notice(PRE), notice(INI, map_of="json/MS181101ab-preliminary.json")])
    assert [d.action for d in out] == ["plan", "duplicate", "rerun"]
    assert ledger.event_state("MS230425k").latest_created == out[2].time_created


def test_newest_created_compares_instants_not_strings():
    assert newest_created("2023-04-25T10:56:53.000Z", "2023-04-25T10:56:53.5+00:00") == "2023-04-25T10:56:53.5+00:00"
    assert newest_created(None, "2023-01-01T00:00:00Z") == "2023-01-01T00:00:00Z"
    assert newest_created("2023-01-02T00:00:00Z", "2023-01-01T00:00:00Z") == "2023-01-02T00:00:00Z"


def test_a_retraction_before_any_notice_keeps_an_older_preliminary_unplanned():
    out, ledger = run([notice(RET), notice(PRE), notice(INI)])
    assert [d.action for d in out] == ["ignore", "ignore", "plan"]
    assert "before the retraction" in out[1].reason and "after a retraction" in out[2].reason
