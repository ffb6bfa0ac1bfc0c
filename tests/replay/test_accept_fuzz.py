"""Property-based: whatever a real notice is mutated into, ``accept`` records a decision and never raises."""

from __future__ import annotations

import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store
from mushrooms.handlers.decisions import ACTIONS

from replay_helpers import FAST, created, raw

REL = "live/MS230425k-preliminary.json"
BASE = json.loads(raw(REL))
KEYS = [("superevent_id",), ("alert_type",), ("time_created",), ("event",), ("event", "time"), ("event", "far"),
        ("event", "significant"), ("event", "group"), ("event", "classification"), ("event", "properties"),
        ("event", "skymap"), ("event", "instruments"), ("external_coinc",)]
values = st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12) \
    | st.lists(st.text(max_size=3), max_size=3) | st.dictionaries(st.text(max_size=4), st.floats(), max_size=3) \
    | st.sampled_from(["PRELIMINARY", "RETRACTION", "S230101a", "MS230425k", "2023-04-25T11:00:00Z", "CBC"])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(changes=st.lists(st.tuples(st.sampled_from(KEYS), values), min_size=1, max_size=3))
def test_accept_never_raises(tmp_path_factory, changes):
    store = Store(tmp_path_factory.mktemp("fuzz") / "s.sqlite")
    try:
        p = NoticePipeline.from_config(FAST, store, MemorySink())
        doc = json.loads(json.dumps(BASE))
        for path, value in changes:
            obj = doc
            for k in path[:-1]:
                obj = obj.get(k) if isinstance(obj, dict) else None
            if isinstance(obj, dict):
                obj[path[-1]] = value
        acc = p.accept(json.dumps(doc).encode(), "fuzz", created(REL))
        assert acc.action in ACTIONS
        assert [d["decision"] for d in store.decisions()] == [acc.action]
        assert (acc.job is not None) == (acc.action in ("plan", "rerun"))
    finally:
        store.close()
