"""The outbox's summary page of a published plan (issue 52, LOW): the plan on its sky map, and final once it is.

The daemon's own wiring (``open_pipeline``) plans a real notice (greedy,
nside 64) into an outbox directory; the page drawn beside the plan must
embed the picture with the sky panels (the sky map read back from the
stored notice), not the airmass panel alone.  A revision published with
``final: false`` and then closed by a ``plan_final`` verdict must stop
saying "an optimised one may follow" in its ``.txt`` and ``.html``.
"""

from __future__ import annotations

import base64
import json
import re
import struct
from pathlib import Path

from daemon_helpers import directory_outbox_config, notice_bytes
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.sinks import DirectorySink
from mushrooms.daemon.wiring import open_pipeline
from mushrooms.report.files import SummarisingSink
from mushrooms.scheduler_core.plan.messages import plan_final_message
from mushrooms.tool.config import load_config

SID = "MS181101ab"


def _png_size(page: str) -> tuple[int, int]:
    """Width and height (pixels) of the PNG embedded in a page."""
    (data,) = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page)
    png = base64.b64decode(data)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", png[16:24])


def _outbox(tmp_path: Path) -> Path:
    cfg = tmp_path / "config.toml"
    cfg.write_text(directory_outbox_config(tmp_path) + f"""
""")
    config = load_config(str(cfg))
    pipeline, close = open_pipeline(config, resolve_paths(config.daemon))
    try:
        assert pipeline.handle(notice_bytes(f"{SID}-preliminary.json"), "test:page").decision == "plan"
    finally:
        close()  # the sink draws the pages still waiting
    return tmp_path / "outbox"


def test_the_outbox_page_draws_the_plan_on_its_sky_map(tmp_path) -> None:
    out = _outbox(tmp_path)
    (page,) = out.glob("mushrooms-*.html")
    width, height = _png_size(page.read_text())
    # the picture with the sky panels is 13 x 11.5 in; the airmass panel and timeline alone 12 x 4.8 in
    assert height > 0.8 * width, (width, height)


def test_a_plan_final_verdict_makes_the_published_summaries_final(tmp_path) -> None:
    from mushrooms.scheduler_core import PlanningConfig, make_plan, read_skymap
    from mushrooms.scheduler_core.plan.messages import revision_document

    skymap = Path(__file__).resolve().parents[1] / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"
    cfg = PlanningConfig(solver="greedy", nside=64)
    doc = revision_document(make_plan(read_skymap(skymap, nside=64), cfg), 1, False)
    sink = SummarisingSink(DirectorySink(tmp_path))
    try:
        sink.publish(doc)
        txt = (tmp_path / f"{doc['plan_id']}.txt")
        assert "an optimised one may follow" in txt.read_text()  # published while the optimiser runs
        sink.publish(plan_final_message(doc["plan_id"], None, "The first plan stands.", "2026-06-05T23:50:00Z"))
    finally:
        sink.close()
    text = txt.read_text()
    assert "may follow" not in text and "may be superseded" not in text and "revision 1 (final)" in text, text
    page = (tmp_path / f"{doc['plan_id']}.html").read_text()
    assert "may follow" not in page and "revision 1 (final)" in page
    assert json.loads((tmp_path / f"{doc['plan_id']}.json").read_text())["final"] is False  # the JSON stays
