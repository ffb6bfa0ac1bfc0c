"""A large file of bad executed records is read in bounded memory (issue 52, LOW: 100 MB cost +433 MB).

A 64 MiB JSON-lines file of malformed records (bad JSON, wrong types, one
line of 8 MiB), read by ``mushrooms plan --executed``'s reader and by the
service's ``file:`` source (:class:`~mushrooms.daemon.loop.fetch.ExecutedReader`),
each in a fresh interpreter: its peak resident memory may grow by far less
than the file.  The good record among them is still read.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

GOOD = {"field_id": 600, "filter": "g", "start": "2025-05-14T04:10:00.000Z", "exposure_s": 300.0,
        "processed_fraction": 1.0, "status": "processed"}
FILE_MB = 64
#: Peak growth allowed (MiB) while reading the file: the reader's own buffers, not the file.
GROWTH_MB = 24

PROBE = """
import sys
from pathlib import Path
sys.path.insert(0, sys.argv[3])
from astropy.time import Time
from mushrooms.handlers.executed import read_jsonl
from mushrooms.daemon.loop.fetch import ExecutedReader
from mushrooms.handlers.executed_source import parse_executed_source
import mushrooms.scheduler_core.executed
def peak():  # this process's own peak (VmHWM: getrusage's ru_maxrss also holds the parent's peak before exec)
    status = open("/proc/self/status").read()
    return float(status.split("VmHWM:")[1].split()[0]) / 1024.0
before = peak()
if sys.argv[2] == "plan":
    got = read_jsonl(Path(sys.argv[1]))
else:
    reader = ExecutedReader(parse_executed_source("file:" + sys.argv[1]), None, 5.0)
    got = reader.read(Time("2025-05-14T03:00:00"), Time("2025-05-14T06:00:00"))
print(len(got), round(peak() - before, 1))
"""


@pytest.fixture(scope="module")
def bad_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("executed") / "bad.jsonl"
    bad_json = b'{"field_id": 601, "filter": "g", "start": "2025-05-14T04:1' + b"\n"
    bad_type = json.dumps(dict(GOOD, field_id="six hundred")).encode() + b"\n"
    with path.open("wb") as fh:
        fh.write(json.dumps(GOOD).encode() + b"\n")
        fh.write(b'{"note": "' + b"x" * (8 << 20) + b'"}\n')  # one line of 8 MiB
        block = bad_json * 4095 + bad_type  # mostly cheap to refuse: a record of the wrong type costs a time parse
        while fh.tell() < FILE_MB << 20:
            fh.write(block)
    return path


@pytest.mark.parametrize("who", ["plan", "service"])
def test_a_large_file_of_bad_records_is_read_in_bounded_memory(bad_file, who):
    root = str(Path(__file__).resolve().parents[2])
    r = subprocess.run([sys.executable, "-c", PROBE, str(bad_file), who, root], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    n, growth = r.stdout.split()
    assert int(n) == 1  # the good record
    assert float(growth) < GROWTH_MB, f"{who}: peak memory grew by {growth} MiB reading a {FILE_MB} MiB file"


def test_a_record_with_an_integer_too_long_for_python_is_one_malformed_line(caplog):
    """``json.loads`` refuses an integer of more than 4300 digits with a ValueError, not a JSONDecodeError:
    the line is malformed like any other (it raised out of the reader)."""
    import logging

    from mushrooms.handlers.executed import read_jsonl

    caplog.set_level(logging.WARNING, logger="mushrooms.handlers.executed")
    got = read_jsonl(json.dumps(GOOD) + "\n" + '{"field_id": ' + "9" * 5000 + "}\n")
    assert [e.field_id for e in got] == [600]
    (message,) = [r.getMessage() for r in caplog.records]
    assert message.startswith("executed file line 2: ") and "\n" not in message
