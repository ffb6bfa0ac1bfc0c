"""What a file of executed records of the wrong type costs to read ("mend" item 4).

Writes a JSON-lines file of ``--lines`` records, each with one value of the wrong
type or out of range and a valid ``start`` (as
``tests/handlers/test_executed_cheap_checks.py`` does), then reads it with
``read_jsonl`` from an open file, in this process, with ``mushrooms`` imported
from ``--code``: prints the wall time, the number of astropy ``Time`` objects
built and the peak Python allocation (tracemalloc), with the load average.

    python benchmarks/attacks/executed_wrong_type.py [--code DIR] [--lines 100000]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

GOOD = {"field_id": 600, "filter": "g", "start": "2025-05-14T04:10:00.000Z", "exposure_s": 300.0,
        "processed_fraction": 1.0, "status": "processed"}
WRONG = [{"field_id": "six hundred"}, {"filter": 1}, {"exposure_s": "300"}, {"processed_fraction": "all"},
         {"status": 0}, {"field_id": 10**7}]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--code", default=str(Path(__file__).resolve().parents[2]), help="import mushrooms from here")
    p.add_argument("--lines", type=int, default=100_000)
    args = p.parse_args()
    sys.path.insert(0, str(Path(args.code).resolve()))
    from astropy.time import Time

    from mushrooms.handlers.executed import read_jsonl

    logging.basicConfig(level=logging.ERROR)
    built = [0]
    init = Time.__init__

    def counting(self, *a, **k):
        built[0] += 1
        return init(self, *a, **k)

    Time.__init__ = counting
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "wrong.jsonl"
        lines = [json.dumps(dict(GOOD, **w)).encode() + b"\n" for w in WRONG]
        with path.open("wb") as fh:
            for k in range(args.lines):
                fh.write(lines[k % len(lines)])
        size = path.stat().st_size
        load = os.getloadavg()
        tracemalloc.start()
        t0 = time.perf_counter()
        with path.open("rb") as fh:
            got = read_jsonl(fh)
        wall = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    print(f"code {args.code}: {args.lines} lines ({size / 2**20:.1f} MiB), kept {len(got)}, {wall:.2f} s, "
          f"astropy Time built {built[0]} times, peak Python allocation {peak / 2**20:.2f} MiB "
          f"(tracemalloc on), load before {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
