"""Memory from small notices: the joint-map choice is made off the consume loop.

A notice of a few hundred kB whose GW and combined maps are a gzipped flat
float32 NSIDE 1024 map (50 MB unpacked) used to be decoded whole inside
``accept`` (the consume loop) to check the joint map: +1.2 GB RSS and 3-5 s
per notice.  ``accept`` now reads the joint map's FITS headers only; the
planning job decodes it (streaming reader) and falls back to the GW map when
it does not decode.  Real parts: the pipeline on a SQLite file, greedy at
nside 64, real sky maps.
"""

from __future__ import annotations

import gc
import json
import tracemalloc
from pathlib import Path

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store

from attack_helpers import FAST, MOC_MAP, amplifying_map, grown_gzip, joint_notice, received_at


@pytest.fixture(scope="module")
def flat1024() -> bytes:
    return amplifying_map(order=6)


def _find(obj, key):
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k == key:
                yield v
            else:
                yield from _find(v, key)
    elif isinstance(obj, list):
        for v in obj:
            yield from _find(v, key)


def test_accepting_an_amplifying_joint_notice_does_not_decode_its_maps(tmp_path: Path, flat1024: bytes) -> None:
    raw = joint_notice("MS181101ab", flat1024, flat1024)
    assert len(raw) < 1 << 20  # small on the wire; each map unpacks to 50 MB
    p = NoticePipeline.from_config(FAST, Store(tmp_path / "s.sqlite"), MemorySink())
    gc.collect()  # astropy's FITS_rec.__del__ of the map just built copies its column: not accept's memory
    tracemalloc.start()
    try:
        acc = p.accept(raw, "kafka:t:0:1", received_at())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert acc.action == "plan" and acc.job is not None, acc.reason
    # the consume loop's share: far below one unpacked map (50 MB); the decode is the job's
    assert peak < 16 << 20, f"accept allocated {peak / 2**20:.1f} MiB at its peak"
    out = p.run_job(acc.job)
    assert out.decision in ("plan", "not_observable"), out.reason
    (doc,) = [m for m in p.sink.messages if m.get("type") in ("plan", "not_observable")]
    assert "combined" in set(_find(doc, "localization"))  # the job decoded the joint map and planned on it


def test_a_joint_map_that_only_fails_when_decoded_falls_back_to_the_gw_map(tmp_path: Path) -> None:
    """Headers fine, body not (a valid table followed by a gzip bomb): the job plans on the GW map."""
    raw = joint_notice("MS181101ab", MOC_MAP.read_bytes(), grown_gzip(8 << 20))
    p = NoticePipeline.from_config(FAST, Store(tmp_path / "s.sqlite"), MemorySink())
    acc = p.accept(raw, "kafka:t:0:1", received_at())
    assert acc.action == "plan" and acc.job is not None, acc.reason
    out = p.run_job(acc.job)
    assert out.decision in ("plan", "not_observable"), out.reason
    (doc,) = [m for m in p.sink.messages if m.get("type") in ("plan", "not_observable")]
    assert set(_find(doc, "localization")) == {"gw"}
    assert json.dumps(doc).count("NaN") == 0
