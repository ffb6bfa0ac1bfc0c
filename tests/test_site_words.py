"""A plan's summary, page and answer name its own telescope and site (issue 53: several telescopes).

LS4's plan (La Silla, America/Santiago) used to say "at Palomar" with Pacific
times, "ZTF plan", "not observable by ZTF", the Moon seen from Palomar and an
area read from ZTF's field grid for LS4's field ids.  The site now comes from
the plan's description (``[site] name``, ``timezone``); ZTF's and WINTER's
(Palomar) words are unchanged.  The plans are the service's own
(``tests/daemon/data``: MS181101ab planned with four telescopes).
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path
from zoneinfo import ZoneInfo

DATA = Path(__file__).resolve().parent / "daemon" / "data"
NOW = dt.datetime(2026, 12, 6, 21, 0, tzinfo=dt.timezone.utc)


def _doc(name: str) -> dict:
    return json.loads((DATA / f"{name}_part_plan.json").read_text())


def _first(doc: dict) -> dt.datetime:
    start = min(o["start"] for o in doc["observations"])
    return dt.datetime.fromisoformat(start.replace("Z", "+00:00"))


def test_an_ls4_summary_says_la_silla_and_chilean_time_never_palomar():
    from mushrooms.report.summary import summary_text

    doc = _doc("ls4")
    text = summary_text(doc, now=NOW)
    chile = _first(doc).astimezone(ZoneInfo("America/Santiago")).strftime("%H:%M %Z")
    assert "Palomar" not in text and "PST" not in text and "PDT" not in text
    assert f"UTC ({chile} at La Silla)" in text
    assert text.count("at La Silla") == 2  # the first exposure and the last one's end
    assert "the fields cover 11,249" not in text  # LS4's fields never read on ZTF's grid (its own area: see
    # tests/test_covered_area_telescopes.py)


def test_an_ls4_page_names_ls4_and_la_silla():
    from mushrooms.report.page import summary_html

    page = summary_html(_doc("ls4"), now=NOW)
    assert "Palomar" not in page and "ZTF plan" not in page
    assert "LS4 plan" in page and "at La Silla" in page and "distance from the Moon at the start (La Silla)" in page


def test_the_moon_is_seen_from_the_plans_own_site():
    from mushrooms.report.facts import plan_facts
    from mushrooms.report.sky import moon_distances

    facts = plan_facts(_doc("ls4"))
    here, palomar = moon_distances(facts.rows, facts.site), moon_distances(facts.rows)
    assert facts.site.name == "La Silla" and None not in here
    assert max(abs(a - b) for a, b in zip(here, palomar)) > 0.05  # topocentric parallax: another site, another Moon


def test_not_observable_by_the_plans_own_telescope():
    from mushrooms.report.summary import answer_line, summary_text

    doc = {**_doc("ls4"), "type": "not_observable", "observations": [],
           "reasons": [{"sentence": "the 90 % region is north of LS4's declination limit"}]}
    assert "NOT OBSERVABLE by LS4: the 90 %" in summary_text(doc, now=NOW)
    assert "not observable by LS4" in answer_line(doc) and "ZTF" not in answer_line(doc)


def test_winter_and_ztf_still_say_palomar_in_pacific_time():
    from mushrooms.report.summary import summary_text

    winter = _doc("winter")
    pacific = _first(winter).astimezone(ZoneInfo("America/Los_Angeles")).strftime("%H:%M %Z")
    assert f"UTC ({pacific} at Palomar)" in summary_text(winter, now=NOW)
    ztf = {**winter, "telescope": "ZTF", "config": {k: v for k, v in winter["config"].items() if k != "telescopes"}}
    assert f"UTC ({pacific} at Palomar)" in summary_text(ztf, now=NOW)


def test_a_description_names_its_site_and_a_bad_zone_is_refused(tmp_path):
    import pytest

    from mushrooms.scheduler_core.instruments import load_description
    from mushrooms.scheduler_core.instruments.loader import DATA_DIR

    assert [(load_description(n).site.name, load_description(n).site.timezone) for n in ("ztf", "ls4", "decam")] == [
        ("Palomar", "America/Los_Angeles"), ("La Silla", "America/Santiago"), ("Cerro Tololo", "America/Santiago")]
    text = (DATA_DIR / "ls4.toml").read_text().replace('timezone = "America/Santiago"', 'timezone = "Mars/Olympus"')
    (tmp_path / "bad.toml").write_text(text.replace('name = "ls4"', 'name = "bad"'))
    with pytest.raises(ValueError, match="timezone"):
        load_description(tmp_path / "bad.toml")


def test_the_parts_lines_and_webhook_words_name_each_telescopes_site():
    from mushrooms.daemon.planning.parts import parts_lines, parts_words

    parts = [{"telescope": "ls4", "queue": "target_list", "state": "exported", "plan_id": "mushrooms-1", "folder": "/o"},
             {"telescope": "decam", "queue": "target_list", "state": "not_observable", "detail": "south"},
             {"telescope": "winter", "queue": "skyportal", "state": "exported", "plan_id": "mushrooms-2"},
             {"telescope": "w", "queue": "skyportal", "state": "failed", "detail": "a description file"}]
    lines = parts_lines(parts)
    assert lines[0] == "Telescopes ztf (ztf_too): this plan at Palomar"
    assert "ls4 (target_list): exported at La Silla mushrooms-1 in /o" in "\n".join(lines)
    assert "decam (target_list): not_observable at Cerro Tololo: south" in "\n".join(lines)
    assert "w (skyportal): failed: a description file" in "\n".join(lines)  # no site known: none said
    assert parts_words(parts) == ("other telescopes: decam target_list not_observable at Cerro Tololo, ls4 target_list "
                                  "exported at La Silla, w skyportal failed, winter skyportal exported at Palomar")
