"""The text and HTML summaries of a plan revision, read from a real plan document.

The plan is a real greedy plan of a real sky map; the event facts an alert adds
(classification, false-alarm rate) and a re-plan's executed coverage are set on
copies of its document, the way the service's documents carry them.
"""

from __future__ import annotations

import copy
import datetime as dt
import re
from pathlib import Path

import pytest

from mushrooms.report.files import revision_in_force, write_summaries
from mushrooms.report.summary import answer_line, summary_text

MAP = Path(__file__).resolve().parent / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"


@pytest.fixture(scope="module")
def doc():
    from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap

    cfg = PlanningConfig(solver="greedy", nside=64)
    d = make_plan(read_skymap(MAP, nside=cfg.nside), cfg).to_document()
    d.update(type="plan", revision=1, final=False)
    d["event"] = dict(d["event"], superevent_id="MS220722v", alert_type="PRELIMINARY",
                      classification={"BNS": 0.9, "NSBH": 0.05, "Terrestrial": 0.05}, far_hz=1e-10)
    return d


def test_the_summary_tells_the_event_the_timing_and_one_row_per_exposure(doc):
    first = dt.datetime.fromisoformat(doc["observations"][0]["start"].replace("Z", "+00:00"))
    text = summary_text(doc, now=first - dt.timedelta(hours=4, minutes=45))
    assert "Event      MS220722v (PRELIMINARY)" in text
    assert "Source     BNS 90 %, NSBH 5 %, Terrestrial 5 %; p_astro 0.95" in text
    assert "one false alarm per 3.2e+02 years" in text
    assert "Queue" not in text  # no name is guessed: the caller gives the names of the one rule
    names = ("ToO_GW_MS220722v_0123abcd_1", "ToO_GW_MS220722v_0123abcd_2", "ToO_GW_MS220722v_0123abcd_3")
    named = summary_text(doc, queues=names, queue_note="submitted to kowalski")
    assert ("Queue      3 queues, one per filter pass; submitted to kowalski: ToO_GW_MS220722v_0123abcd_1 … "
            "ToO_GW_MS220722v_0123abcd_3\n") in named
    assert re.search(r"First      \d{4}-\d\d-\d\d \d\d:\d\d UTC \(\d\d:\d\d P[DS]T at Palomar\), starts in 4 h 45 min",
                     text)
    rows = [line for line in text.splitlines() if re.match(r"^\s+\d+\s+[gri]\s+\d\d-\d\d ", line)]
    assert len(rows) == len(doc["observations"])
    last = doc["observations"][-1]
    assert rows[-1].rstrip().endswith(f"{100 * last['coverage_after']:.1f} %")  # the cumulative coverage
    assert "(may be superseded)" in text and "an optimised one may follow" in text


def test_a_replan_summary_says_what_was_done_what_is_added_and_the_total(doc):
    replan = copy.deepcopy(doc)
    replan["metrics"]["coverage_executed"] = 0.125
    cov = replan["metrics"]["coverage"]
    text = summary_text(replan)
    assert "Done       12.5 % of the probability was already covered" in text
    assert f"Added      this plan adds {100 * cov:.1f} %" in text
    assert f"Total      {100 * (cov + 0.125):.1f} % of the probability after this plan" in text
    assert f"adding {100 * cov:.1f} % to the 12.5 % done (total {100 * (cov + 0.125):.1f} %)" in answer_line(replan)


def test_the_certified_bound_is_one_plain_sentence(doc):
    bounded = copy.deepcopy(doc)
    bounded["metrics"].update(upper_bound=0.665, status="optimal")
    text = summary_text(bounded)
    assert "No plan that obeys these rules can cover more than 66.5 %." in text
    assert "\"optimal\" means best within the solver's model" in text
    assert "(no plan can cover more than 66.5 %)" in answer_line(bounded)


def test_a_plan_ending_the_next_utc_day_says_so(doc):
    late = copy.deepcopy(doc)
    last = late["observations"][-1]
    end = dt.datetime.fromisoformat(last["end"].replace("Z", "+00:00"))
    last["end"] = (end.replace(hour=0, minute=30) + dt.timedelta(days=1)).isoformat().replace("+00:00", "Z")
    assert re.search(r"to 00:30 UTC the next day, covering", answer_line(late))
    assert " the next day" not in answer_line(doc)


def test_a_plan_final_verdict_makes_the_revision_it_names_final(doc):
    verdict = {"type": "plan_final", "plan_id": doc["plan_id"], "reason": "The first plan stands."}
    in_force = revision_in_force([doc, verdict])
    assert in_force["final"] is True and doc["final"] is False
    assert "revision 1 (final)" in summary_text(in_force)
    assert revision_in_force([doc])["final"] is False and revision_in_force([verdict]) is None


def test_the_page_embeds_the_picture_and_a_row_per_exposure(doc, tmp_path):
    png = b"\x89PNG\r\n\x1a\n" + b"0" * 64
    txt, page = write_summaries(doc, tmp_path / "P.json", png)
    body = page.read_text()
    assert txt.read_text().startswith(f"Revision   {doc['plan_id']}")
    assert "data:image/png;base64,iVBORw0KGgo" in body
    assert body.count("<tr") >= len(doc["observations"])
    assert "<script" not in body.lower()


def test_hostile_text_in_the_document_is_escaped_on_the_page(doc, tmp_path):
    hostile = copy.deepcopy(doc)
    hostile["event"]["superevent_id"] = "<script>alert(1)</script>"
    _, page = write_summaries(hostile, tmp_path / "H.json")
    body = page.read_text()
    assert "<script>" not in body and "&lt;script&gt;alert(1)&lt;/script&gt;" in body
