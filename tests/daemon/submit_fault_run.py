"""``mushrooms run`` that kills itself with SIGKILL at one point of a Kowalski submission (tests only).

``MUSHROOMS_TEST_SUBMIT_KILL``:

* ``before_put``: the attempt is committed, the PUT not sent;
* ``after_put``: the server took the PUT and answered; the answer is not committed;
* ``after_put:<n>``: the same after the n-th PUT of the run (a kill inside a queue set).

A kill *during* a DELETE is made by the contract server instead (it applies
the DELETE and holds its answer while the test kills the daemon).
"""

from __future__ import annotations

import os
import signal
import sys


def install(point: str) -> None:
    from mushrooms.daemon.submission.remote import KowalskiQueue

    real_put = KowalskiQueue.put
    point, _, nth = point.partition(":")
    calls = []

    def put(self, queue):
        if point == "before_put":
            os.kill(os.getpid(), signal.SIGKILL)
        answer = real_put(self, queue)
        calls.append(queue.get("queue_name"))
        if point == "after_put" and len(calls) == int(nth or 1):
            os.kill(os.getpid(), signal.SIGKILL)
        return answer

    KowalskiQueue.put = put


if __name__ == "__main__":
    install(os.environ["MUSHROOMS_TEST_SUBMIT_KILL"])
    from mushrooms.cli import main

    sys.exit(main(["run", *sys.argv[1:]]))
