"""The service with two or more telescopes (issue 53, phase 4), in process: config, pipeline, notices, the outbox.

Shared by ``test_telescope_parts.py`` and ``telescope_parts_kill.py`` (the kill -9 run).
"""

from __future__ import annotations

import base64
import io
import json
from pathlib import Path
from typing import Any

from daemon_helpers import directory_outbox_config, notice_bytes

SID = "MS181101ab"
#: The shipped telescope descriptions.
SHIPPED = Path(__file__).resolve().parents[2] / "mushrooms" / "scheduler_core" / "data" / "telescopes"


def parts_config(tmp_path: Path, telescopes: list[str]) -> Path:
    """A directory-outbox service config (greedy, nside 64) planning ``telescopes``."""
    cfg = tmp_path / "config.toml"
    listed = ", ".join(json.dumps(t) for t in telescopes)
    cfg.write_text(directory_outbox_config(tmp_path).replace("[scheduler]\n", f"[scheduler]\ntelescopes = [{listed}]\n"))
    return cfg


def open_parts_pipeline(cfg: Path) -> tuple[Any, Any]:
    """The daemon's own wiring (``open_pipeline``) on ``cfg``: (pipeline, close)."""
    from mushrooms.daemon.settings import resolve_paths
    from mushrooms.daemon.wiring import open_pipeline
    from mushrooms.tool.config import load_config

    config = load_config(str(cfg))
    return open_pipeline(config, resolve_paths(config.daemon))


def newer_map_update() -> bytes:
    """MS181101ab's UPDATE with another sky map (one more header card: other bytes, another SHA-256)."""
    from astropy.io import fits

    doc = json.loads(notice_bytes(f"{SID}-update.json"))
    with fits.open(io.BytesIO(base64.b64decode(doc["event"]["skymap"]))) as hdus:
        hdus[1].header["HISTORY"] = "refined localisation (test)"
        out = io.BytesIO()
        hdus.writeto(out)
    doc["event"]["skymap"] = base64.b64encode(out.getvalue()).decode()
    return json.dumps(doc).encode()


def part_folders(outbox: Path) -> dict[tuple[str, str], Path]:
    """(job folder, telescope) -> the part's folder, for every part in the outbox."""
    return {(p.parent.parent.name, p.parent.name): p.parent
            for p in sorted((outbox / "telescopes").glob("*/*/*/part.json"))}


def part(folder: Path) -> dict[str, Any]:
    return json.loads((folder / "part.json").read_text())


def part_rows(state: Path) -> list[tuple[int, str, str, str | None]]:
    """(job_id, telescope, state, plan_id) of every ``telescope_parts`` row."""
    import sqlite3

    conn = sqlite3.connect(state)
    try:
        return [tuple(r) for r in conn.execute(
            "SELECT job_id, telescope, state, plan_id FROM telescope_parts ORDER BY job_id, telescope")]
    finally:
        conn.close()
