"""Property-based: random mutations of real notices never escape parse_notice as anything but NoticeError."""

from __future__ import annotations

import copy
import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mushrooms.handlers.alert import Alert, NoticeError, parse_notice

from notice_helpers import notice_bytes, notice_dict

SOURCES = ["json/MS181101ab-preliminary.json", "json/MS181101ab-retraction.json",
           "live/S230528ay-preliminary.json", "json/MS181101ab-ext-update.json"]
RECORDS = {rel: notice_dict(rel) for rel in SOURCES}
AVRO = notice_bytes("avro/MS181101ab-earlywarning.avro")
SMALL = notice_bytes("json/MS181101ab-retraction.json")

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=20),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=10,
)


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))


def check(data: bytes) -> None:
    try:
        a = parse_notice(data, max_bytes=8_388_608)
    except NoticeError as exc:
        text = str(exc)
        assert text and "\n" not in text
    else:
        assert isinstance(a, Alert)
        assert a.superevent_id and a.alert_type
        assert (a.event is None) == (a.alert_type == "RETRACTION")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(src=st.sampled_from(SOURCES), data=st.data(), value=json_values, delete=st.booleans())
def test_structural_mutations(src, data, value, delete):
    rec = copy.deepcopy(RECORDS[src])
    paths = [p for p in _paths(rec) if p]
    path = data.draw(st.sampled_from(paths))
    parent = rec
    for k in path[:-1]:
        parent = parent[k]
    if delete:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    check(json.dumps(rec).encode())


@settings(max_examples=150, deadline=None)
@given(data=st.data(), blob=st.sampled_from([SMALL, AVRO[:20000]]))
def test_byte_level_mutations(data, blob):
    buf = bytearray(blob)
    for _ in range(data.draw(st.integers(1, 8))):
        i = data.draw(st.integers(0, len(buf) - 1))
        buf[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(buf)))
    check(bytes(buf[:cut]))


@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_avro_byte_mutations(data):
    buf = bytearray(AVRO)
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, 2000))  # header, schema and the record's leading fields
        buf[i] = data.draw(st.integers(0, 255))
    check(bytes(buf))


@given(st.binary(max_size=2000))
def test_arbitrary_bytes(blob):
    check(blob)
