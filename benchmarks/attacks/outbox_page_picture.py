"""The picture on the outbox's summary page of a plan the daemon's own wiring published (issue 52, LOW).

Plans one sample notice (greedy, nside 64) through ``open_pipeline`` (the
store and the outbox directory exactly as ``mushrooms run`` opens them) and
writes the PNG embedded in the plan's ``.html`` to ``OUT.png``::

    PYTHONPATH=<checkout> python benchmarks/attacks/outbox_page_picture.py OUT.png [NOTICE]

Run it on two checkouts to compare their pages (before/after).
"""

from __future__ import annotations

import base64
import re
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
NOTICE = REPO / "tests" / "data" / "notices" / "json" / "MS181101ab-preliminary.json"

CONFIG = """
[scheduler]
solver = "greedy"
nside = 64
time_step_s = 600.0

[policy]
allow_mock = true
max_notice_age_s = 0
max_event_age_s = 0

[daemon]
state_path = "{tmp}/state.sqlite"

[outbound]
sink = "directory"
directory = "{tmp}/outbox"
"""


def main(out: str, notice: str = str(NOTICE)) -> int:
    from mushrooms.daemon.settings import resolve_paths
    from mushrooms.daemon.wiring import open_pipeline
    from mushrooms.offline import configure_astropy_offline
    from mushrooms.tool.config import load_config

    configure_astropy_offline()  # as the service does: no IERS download

    with tempfile.TemporaryDirectory() as tmp:
        cfg = Path(tmp) / "config.toml"
        cfg.write_text(CONFIG.format(tmp=tmp))
        config = load_config(str(cfg))
        pipeline, close = open_pipeline(config, resolve_paths(config.daemon))
        try:
            outcome = pipeline.handle(Path(notice).read_bytes(), "attack:outbox-page")
        finally:
            close()
        print(f"decision {outcome.decision}")
        (page,) = (Path(tmp) / "outbox").glob("mushrooms-*.html")
        (data,) = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page.read_text())
        Path(out).write_bytes(base64.b64decode(data))
        print(f"{out}: the picture of {page.name}")
        txt = page.with_suffix(".txt").read_text()
        print("\n".join(line for line in txt.splitlines()[:16]))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
