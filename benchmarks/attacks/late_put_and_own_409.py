"""Issue 52, findings 1 and 4 and LOW "settling a set DELETEs names never PUT", on loopback, in one run.

Real plans (the notice pipeline, greedy, nside 64), a real state file, the
Kowalski contract server of ``tests/daemon/contract_servers.py`` with the real
queue-set export (K = the plan's filter passes).  Scenarios:

``update``      revision 1's first PUT is applied only after the client's deadline; an updated map
                settles revision 1; then the late PUT lands; the submitter passes twice more.
``retraction``  the same, settled by a retraction, with a restart before the PUT lands.
``kill_put3``   kill -9 (in process) after Kowalski accepted PUT #3 of revision 1; the telescope then
                observes the first target of queue 3; the restart goes on.

Each prints one JSON line: the queues live at the end that should not be, the revision's
rows' states, the DELETEs of names never PUT, and the request log.  Which ``mushrooms`` is
measured is the one on ``sys.path`` (``PYTHONPATH=/path/to/checkout``)::

    PYTHONPATH=$PWD python benchmarks/attacks/late_put_and_own_409.py
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests" / "daemon"), str(ROOT / "tests")]

SID = "MS181101ab"
LATER = "2023-04-26T00:00:00Z"


def _states(w) -> list[list]:
    from mushrooms.daemon.submission.submitter import submissions

    return [[s.revision, s.state] for s in submissions(w.store) if s.revision is not None]


def _names(w, revision: int) -> list[str]:
    from mushrooms.daemon.submission.submitter import submissions

    row = next(s for s in submissions(w.store) if s.revision == revision)
    return [q["queue_name"] for q in row.body]


def _report(scenario: str, w, kowalski, wanted: set[str], put_ever: set[str]) -> dict:
    deletes = [e["queue_name"] for e in kowalski.log if e["method"] == "DELETE"]
    return {"scenario": scenario, "live_that_should_not_be": sorted(set(kowalski.queues) - wanted),
            "wanted_missing": sorted(wanted - set(kowalski.queues)), "states": _states(w),
            "deletes_of_names_never_put": sorted(set(deletes) - put_ever), "requests": kowalski.lines()}


def _put_ever(kowalski) -> set[str]:
    return {e["queue_name"] for e in kowalski.log if e["method"] == "PUT" and e["status"] in (200, 409)}


def late(scenario: str) -> dict:
    from contract_servers import KowalskiContract, loopback_server
    from test_submissions import TOKEN, World, _config

    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    kowalski.hang_s = 60.0
    first = f"ToO_GW_{SID}_r1_1"
    kowalski.faults_by_name["PUT", first] = ["late"]
    with tempfile.TemporaryDirectory() as tmp:
        w = World(Path(tmp) / "state.sqlite", _config(kowalski.url, timeout_s=1.0))
        try:
            w.notice("MS181101ab-preliminary.json")
            w.submitter.step()
            assert kowalski.late_held.wait(10)
            if scenario == "update":
                w.notice("MS230425l-preliminary.json", SID)
            else:
                w.notice("MS181101ab-retraction.json", time_created=LATER)
            w.submitter.step()
            if scenario == "retraction":
                w.restart()
            kowalski.land.set()
            assert kowalski.landed.wait(10)
            w.submitter.step()
            w.submitter.step()
            wanted = set(_names(w, 2)) if scenario == "update" else set()
            return _report(scenario, w, kowalski, wanted, _put_ever(kowalski))
        finally:
            kowalski.land.set()
            w.store.close()
            server.clear()
            server.stop()


def kill_put3() -> dict:
    from contract_servers import KowalskiContract, loopback_server
    from test_submissions import TOKEN, Killed, World, _config, _die_after

    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    with tempfile.TemporaryDirectory() as tmp:
        w = World(Path(tmp) / "state.sqlite", _config(kowalski.url))
        try:
            w.notice("MS181101ab-preliminary.json")
            _die_after(w.submitter.client, "put", nth=3)
            try:
                w.submitter.step()
            except Killed:
                pass
            third = _names(w, 1)[2]
            listed = kowalski.queues[third]
            kowalski.queues[third] = {**listed, "targets": listed["targets"][1:]}
            w.restart()
            w.submitter.step()
            return _report("kill_put3", w, kowalski, set(_names(w, 1)), _put_ever(kowalski))
        finally:
            w.store.close()
            server.clear()
            server.stop()


def main() -> int:
    from astropy.utils import iers

    import mushrooms

    iers.conf.auto_download = False  # no network (as tests/conftest.py)
    iers.conf.auto_max_age = None

    print(json.dumps({"mushrooms": str(Path(mushrooms.__file__).parent)}))
    for one in (lambda: late("update"), lambda: late("retraction"), kill_put3):
        out = one()
        print(json.dumps({k: v for k, v in out.items() if k != "requests"}))
        print(json.dumps({"requests": out["requests"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
