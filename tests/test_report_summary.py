"""The text and HTML summaries of a plan revision, read from a real plan document.

The plan is a real greedy plan of a real sky map; the event facts an alert adds
(classification, false-alarm rate) and a re-plan's executed coverage are set on
copies of its document, the way the service's documents carry them.
"""

from __future__ import annotations

import copy
import datetime as dt
import re
import tempfile
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


def _table(text: str) -> tuple[list[str], list[list[str]]]:
    """The exposure table of a text summary: its header words and its rows' words."""
    lines = text.splitlines()
    k = next(i for i, line in enumerate(lines) if line.split()[:2] == ["field", "filter"])
    return lines[k].split(), [line.split() for line in lines[k + 1:] if line.strip()]


def test_the_exposure_table_gives_each_exposure_its_place_exposure_time_and_moon_distance(doc):
    from astropy import units as u
    from astropy.coordinates import SkyCoord, get_body
    from astropy.time import Time

    from mushrooms.scheduler_core.sky.visibility import site

    head, rows = _table(summary_text(doc))
    assert head[:8] == ["field", "filter", "start", "(UTC)", "RA", "Dec", "exp", "Moon"], head
    obs = doc["observations"]
    times = Time([o["start"].rstrip("Z") for o in obs], scale="utc")
    moon = get_body("moon", times, site())
    # in the Moon's frame (topocentric GCRS): a field's direction is the same there, the Moon's would not be in ICRS
    want = moon.separation(SkyCoord([o["ra"] for o in obs] * u.deg, [o["dec"] for o in obs] * u.deg)).deg
    for row, o, sep in zip(rows, obs, want):
        assert float(row[4]) == pytest.approx(o["ra"], abs=0.01) and float(row[5]) == pytest.approx(o["dec"], abs=0.01)
        assert row[6] == f"{o['exposure_s']:.0f}s"
        assert float(row[7].rstrip("°")) == pytest.approx(sep, abs=1.0)  # shown to the degree
    page = write_summaries(doc, Path(tempfile.mkdtemp()) / "P.json")[1].read_text()
    for label in ("RA (deg)", "Dec (deg)", "exposure (s)", "Moon (deg)"):
        assert f">{label}</th>" in page


def test_the_facts_give_the_covered_area_and_the_delay_from_the_merger_and_the_alert(doc):
    alerted = copy.deepcopy(doc)
    merger = dt.datetime.fromisoformat(doc["event"]["event_time"].replace("Z", "+00:00"))
    first = dt.datetime.fromisoformat(doc["observations"][0]["start"].replace("Z", "+00:00"))
    alerted["event"]["time_created"] = (merger + dt.timedelta(minutes=7)).isoformat().replace("+00:00", "Z")
    text = summary_text(alerted)
    delay = round((first - merger).total_seconds() / 60.0)
    words = f"{delay // 60} h {delay % 60} min" if delay >= 60 else f"{delay} min"
    assert f"Delay      first exposure {words} after the merger, " in text, text
    area = re.search(r"^Area       .*; the fields cover ([0-9,]+) deg²", text, re.M)
    assert area, text
    n_fields = len({o["field_id"] for o in doc["observations"]})
    # a ZTF field is 47 deg² of sky (its CCDs): the union is at most that per field, and at least one field
    assert 40.0 <= float(area[1].replace(",", "")) <= 50.0 * n_fields
    one = copy.deepcopy(doc)
    one["observations"] = [o for o in doc["observations"] if o["field_id"] == doc["observations"][0]["field_id"]]
    single = float(re.search(r"the fields cover ([0-9,]+) deg²", summary_text(one))[1].replace(",", ""))
    assert 40.0 <= single <= 50.0  # nside 64: pixels of 0.84 deg²
    assert "after the merger" in write_summaries(alerted, Path(tempfile.mkdtemp()) / "P.json")[1].read_text()
