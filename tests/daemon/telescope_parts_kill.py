"""Plan MS181101ab's PRELIMINARY with ztf, ls4 and decam, and SIGKILL itself after ls4's part (tests only).

``python telescope_parts_kill.py CONFIG``: the daemon's wiring plans the
notice; right after the ls4 part is recorded (its files written, its row
committed) and before decam's, the process kills itself with SIGKILL.
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(cfg: str) -> None:
    from mushrooms.offline import configure_astropy_offline

    configure_astropy_offline()
    from mushrooms.daemon.planning.parts import TelescopeParts
    from daemon_helpers import notice_bytes
    from telescope_parts_setup import SID, open_parts_pipeline

    real = TelescopeParts._export

    def export(self, store, job, telescope, plan, *args, **kw):
        state = real(self, store, job, telescope, plan, *args, **kw)
        if telescope.name == "ls4":
            os.kill(os.getpid(), signal.SIGKILL)
        return state

    TelescopeParts._export = export
    pipeline, _ = open_parts_pipeline(Path(cfg))
    pipeline.handle(notice_bytes(f"{SID}-preliminary.json"), "test:kill")


if __name__ == "__main__":
    main(sys.argv[1])
