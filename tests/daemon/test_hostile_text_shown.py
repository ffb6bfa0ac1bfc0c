"""Text a notice carries reaches the observer's ``.txt``, ``.html`` and ``mushrooms status`` escaped and bounded
(issue 52, LOW).

A real notice, its classification given a key of C1 controls (U+009B is the
8-bit CSI: ``\\x9b2J`` clears a terminal that takes 8-bit controls) and a
right-to-left override, and a key of 200 kB, planned through the daemon's
own wiring (``open_pipeline``, greedy, nside 64) into an outbox; then
``mushrooms status`` on the state file.  No C1 control nor bidi override
may come out raw, and no line may carry the 200 kB key whole.
"""

from __future__ import annotations

import json

from daemon_helpers import directory_outbox_config, notice_bytes
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.wiring import open_pipeline
from mushrooms.handlers.text import storable
from mushrooms.tool import status
from mushrooms.tool.config import load_config

SID = "MS181101ab"
HOSTILE = "\x9b2J\x85\u202eevil\u2066"
HUGE = "K" * 200_000


def _raw(text: str) -> list[str]:
    """C1 controls, bidi embeddings/overrides/isolates and line separators found raw in ``text``."""
    return sorted({f"U+{ord(c):04X}" for c in text if 0x80 <= ord(c) <= 0x9F or 0x202A <= ord(c) <= 0x202E
                   or 0x2066 <= ord(c) <= 0x2069 or c in "\u200e\u200f\u061c\u2028\u2029"})


def test_storable_escapes_c1_controls_bidi_controls_and_line_separators():
    shown = storable("a\x9bb\x85c\u202ed\u2066e\u200ff\u2028g\u061ch")
    assert _raw(shown) == [] and shown.startswith("a\\x9bb\\x85c\\u202ed")
    assert storable("Zoë, 東京, ü") == "Zoë, 東京, ü"  # letters stay


def test_hostile_classification_keys_are_escaped_and_bounded_in_the_summaries_and_status(tmp_path, capsys):
    cfg = tmp_path / "config.toml"
    cfg.write_text(directory_outbox_config(tmp_path) + f"""
""")
    doc = json.loads(notice_bytes(f"{SID}-preliminary.json"))
    doc["event"]["classification"] = {"BNS": 0.9, HOSTILE: 0.05, HUGE: 0.05}
    config = load_config(str(cfg))
    pipeline, close = open_pipeline(config, resolve_paths(config.daemon))
    try:
        assert pipeline.handle(json.dumps(doc).encode(), "test:hostile").decision == "plan"
    finally:
        close()
    (plan,) = [p for p in (tmp_path / "outbox").glob("mushrooms-*.json") if p.stem.count("-") == 1]
    capsys.readouterr()
    status.main(["--state", str(tmp_path / "state.sqlite"), "--config", str(cfg)])
    said = capsys.readouterr().out
    for where, text in (("txt", plan.with_suffix(".txt").read_text()), ("html", plan.with_suffix(".html").read_text()),
                        ("status", said)):
        assert _raw(text) == [], where
        assert "K" * 1000 not in text, where
        assert "\\x9b2J" in text, where  # the key is shown, escaped
