"""Peak memory of reading a large JSON-lines file of bad executed records (issue 52, LOW: 100 MB cost +433 MB).

Writes a file of ``--mb`` MiB (malformed JSON lines and records of the wrong
type, one good record, one 8 MiB line), then reads it in a fresh
interpreter per reader, ``mushrooms plan --executed``'s (``read_jsonl`` on a
path) and the service's ``file:`` source (``ExecutedReader``), and prints
each reader's peak resident-memory growth and wall time::

    PYTHONPATH=<checkout> python benchmarks/attacks/executed_memory.py [--mb 100]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

GOOD = {"field_id": 600, "filter": "g", "start": "2025-05-14T04:10:00.000Z", "exposure_s": 300.0,
        "processed_fraction": 1.0, "status": "processed"}

PROBE = """
import sys, time
from pathlib import Path
from astropy.time import Time
from mushrooms.handlers.executed import read_jsonl
from mushrooms.daemon.loop.fetch import ExecutedReader
from mushrooms.handlers.executed_source import parse_executed_source
import mushrooms.scheduler_core.executed
def peak():  # this process's own peak (VmHWM: getrusage's ru_maxrss also holds the parent's peak before exec)
    status = open("/proc/self/status").read()
    return float(status.split("VmHWM:")[1].split()[0]) / 1024.0
before, t0 = peak(), time.perf_counter()
if sys.argv[2] == "plan":
    got = read_jsonl(Path(sys.argv[1]))
else:
    got = ExecutedReader(parse_executed_source("file:" + sys.argv[1]), None, 5.0).read(
        Time("2025-05-14T03:00:00"), Time("2025-05-14T06:00:00"))
print(f"{sys.argv[2]:8s} records kept {len(got)}  peak RSS growth {peak() - before:7.1f} MiB  "
      f"{time.perf_counter() - t0:5.1f} s")
"""


def write_bad_file(path: Path, mb: int) -> None:
    bad_json = b'{"field_id": 601, "filter": "g", "start": "2025-05-14T04:1' + b"\n"
    bad_type = json.dumps(dict(GOOD, field_id="six hundred")).encode() + b"\n"
    with path.open("wb") as fh:
        fh.write(json.dumps(GOOD).encode() + b"\n")
        fh.write(b'{"note": "' + b"x" * (8 << 20) + b'"}\n')
        block = bad_json * 4095 + bad_type  # mostly cheap to refuse: a record of the wrong type costs a time parse
        while fh.tell() < mb << 20:
            fh.write(block)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mb", type=int, default=100, help="file size (MiB), default 100")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bad.jsonl"
        write_bad_file(path, args.mb)
        print(f"{path.stat().st_size / 2 ** 20:.0f} MiB of bad executed records; load {os.getloadavg()[0]:.1f}")
        for who in ("plan", "service"):
            # cwd: the temporary folder, so that PYTHONPATH (not a checkout in the cwd) names the code measured
            r = subprocess.run([sys.executable, "-c", PROBE, str(path), who], capture_output=True, text=True, cwd=tmp)
            print(r.stdout.strip() or f"{who}: exit {r.returncode}: {r.stderr.strip().splitlines()[-1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
