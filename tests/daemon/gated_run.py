"""``mushrooms run`` with a test gate in front of every planning job's schedulers.

Used by the service tests (``Daemon(..., gate=DIR)``) to hold a job in the
middle of planning for as long as the test needs, instead of hoping that a
real solve is still running when the test acts:

* while ``DIR/hold`` exists, a job entering a scheduler writes
  ``DIR/entered-<superevent>-<solver>`` and waits (polling its stop flag:
  a superseded job still ends at once);
* removing ``DIR/hold`` lets every held job go on with the real scheduler;
* while ``DIR/fail`` exists, a job's scheduler raises (a job that fails);
* while ``DIR/hold-warm`` exists, the daemon's start-up warm-up waits
  (``/readyz`` during warm-up); ``DIR/warming`` says it got there;
* while ``DIR/fail-warm`` exists, the bundled demo sky map the warm-up plans
  is a file that is not FITS (a broken install): the warm-up plan fails.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path


def install(gate: Path) -> None:
    from mushrooms.daemon.planning import revisions as planning

    original_init = planning.JobPlanner.__init__
    original_first = planning.JobPlanner._first_stage

    def first_plan(self, job, should_stop):
        self._gate_sid = job.superevent_id
        return original_first(self, job, should_stop)

    def init(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        real = self.scheduler

        def held(problem, solver, should_stop=None):
            sid = getattr(self, "_gate_sid", "-")
            if (gate / "fail").exists():
                raise RuntimeError("test gate: scheduler failure")
            if (gate / "hold").exists():
                (gate / f"entered-{sid}-{solver}").touch()
                while (gate / "hold").exists():
                    if should_stop is not None and should_stop():
                        break
                    time.sleep(0.02)
            return real(problem, solver, should_stop)

        self.scheduler = held

    planning.JobPlanner.__init__ = init
    planning.JobPlanner._first_stage = first_plan

    from mushrooms.daemon import service

    original_warm = service.Service._warm_up

    def warm_up(self, cache):
        (gate / "warming").touch()  # the start-up reached its warm-up
        while (gate / "hold-warm").exists():
            time.sleep(0.05)
        return original_warm(self, cache)

    service.Service._warm_up = warm_up

    from mushrooms import bundled

    original_demo = bundled.demo_skymap_path

    def demo_skymap_path():
        if (gate / "fail-warm").exists():
            broken = gate / "broken-demo-map.fits"
            broken.write_bytes(b"this is not a FITS file\n" * 200)
            return str(broken)
        return original_demo()

    bundled.demo_skymap_path = demo_skymap_path


if __name__ == "__main__":
    install(Path(os.environ["MUSHROOMS_TEST_GATE"]))
    from mushrooms.cli import main

    sys.exit(main(["run", *sys.argv[1:]]))
