"""The queue tag is 12 hex digits of the plan id; queues named by the 8-digit tag before stay recognised.

Two plans of an event collide in the 8-digit tag with probability about
n^2 / 2 / 16^8 (1.2e-6 for n = 100 plans); 12 digits take it to 1.8e-11 at
the cost of 4 characters per name (docs/design/submission.md).  A daemon
upgraded with queues of the old names live (Y1-Y2 of the same document) must
still know them as its own: each submission row keeps the names it was built
with, so a restart PUTs, recognises (409) and DELETEs the old names, and only
a plan adopted after the upgrade gets the new ones.  Real plans from the notice
pipeline, a real store, Kowalski's contract server on loopback (its ``"late"``
fault holds a PUT past the client's deadline and applies it when told), queue
sets of K = 3 (``test_submission_sets.three_queues``).
"""

from __future__ import annotations

import hashlib
import re

import pytest

from mushrooms.daemon.submission.submitter import submissions
from mushrooms.scheduler_core.plan import exports
from test_submission_sets import names, sets  # noqa: F401 (fixture)
from test_submissions import SID, World, _config, kowalski, server  # noqa: F401 (fixtures)

UPDATE = ("MS230425l-preliminary.json", SID)


def _old_tag(plan_id: str) -> str:
    """The plan tag of the versions before this one: 8 hex digits (the id's first 8, else its SHA-256's)."""
    found = re.fullmatch(r"mushrooms-([0-9a-f]{16})", plan_id)
    return found.group(1)[:8] if found else hashlib.sha256(plan_id.encode()).hexdigest()[:8]


def _states(w: World) -> list[tuple[int, str]]:
    return [(s.revision, s.state) for s in submissions(w.store) if s.revision is not None]


def test_the_plan_tag_is_twelve_hex_digits_of_the_plan_id() -> None:
    assert exports.plan_tag("mushrooms-0123456789abcdef") == "0123456789ab"
    assert exports.queue_name_base("GW", "mushrooms-0123456789abcdef", "S250101a") == "ToO_GW_S250101a_0123456789ab"
    other = exports.plan_tag("a plan id of another form")
    assert re.fullmatch(r"[0-9a-f]{12}", other) and other == hashlib.sha256(b"a plan id of another form").hexdigest()[:12]


@pytest.mark.parametrize("tag", ["0123abcd", "0123456789ab"])
def test_the_queue_tool_groups_old_and_new_names_as_the_services(tag) -> None:
    from mushrooms.tool.queue import render

    queues = [{"queue_name": f"ToO_GW_S250101a_{tag}_{k}", "validity_window_mjd": [61000.0, 61000.5],
               "targets": []} for k in (1, 2)] + [{"queue_name": "someone_elses", "targets": []}]
    text = render(queues)
    assert f"S250101a plan {tag}: 2 queue(s)" in text, text  # grouped under its event and plan
    assert "other queues: 1" in text, text  # only the queue that is not the service's


def test_an_upgraded_daemon_recognises_and_replaces_the_queues_it_sent_under_the_old_names(
        sets, tmp_path, kowalski, monkeypatch) -> None:
    w = World(tmp_path / "state.sqlite", _config(kowalski.url, timeout_s=1.0))
    try:
        with monkeypatch.context() as old:  # the version before the upgrade: 8-digit tags
            old.setattr(exports, "plan_tag", _old_tag)
            kowalski.hang_s = 60.0
            kowalski.faults_by_name["PUT", f"ToO_GW_{SID}_*_2"] = ["late"]  # queue 2: applied after the deadline
            w.notice("MS181101ab-preliminary.json")
            w.submitter.step()
            assert kowalski.late_held.wait(10)
            kowalski.land.set()
            assert kowalski.landed.wait(10)
        sent = names(w, 1)
        assert re.fullmatch(rf"ToO_GW_{SID}_[0-9a-f]{{8}}_1", sent[0]), sent
        assert sorted(kowalski.queues) == sent[:2]  # 1 accepted, 2 applied unanswered; 3 not sent yet
        w.restart()  # the upgraded daemon on the same state file
        w.submitter.step()
        print("\n".join(kowalski.lines()))
        assert sorted(kowalski.queues) == sent, "the restart did not finish the old set under its own names"
        assert _states(w) == [(1, "submitted")]  # queue 2's 409 is ours (Y1): not rejected, no duplicate
        w.notice(*UPDATE)
        w.submitter.step()
        new = names(w, 2)
        assert re.fullmatch(rf"ToO_GW_{SID}_[0-9a-f]{{12}}_1", new[0]), new
        assert sorted(kowalski.queues) == new, "the old 8-digit queues were left live beside the new set"
        assert sorted(e["queue_name"] for e in kowalski.log if e["method"] == "DELETE") == sent
        assert _states(w) == [(1, "replaced"), (2, "submitted")]
    finally:
        kowalski.land.set()
        w.store.close()
