"""docs/operations.md and the daemon's metrics stay in step.

* The metric table lists exactly the metrics a :class:`ServiceMetrics`
  exports (with every scrape-time source present), with their types.
* The alert rules are a well-formed Prometheus rule file whose
  expressions only name metrics of the table (or Prometheus' own ``up``).
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from mushrooms.daemon.ops.metrics import ServiceMetrics
from mushrooms.daemon.state.store import Store

DOC = Path(__file__).resolve().parents[1] / "docs" / "operations.md"


def _table() -> dict[str, str]:
    """metric name -> type, from the doc's metric table."""
    rows = re.findall(r"^\| `(mushrooms_[a-z_]+)` \| ([a-z ()]+) \|", DOC.read_text(), re.MULTILINE)
    return {name: kind.split()[0] for name, kind in rows}


def _exported(tmp_path: Path) -> dict[str, str]:
    """metric name as scraped (``_total`` on counters, ``_info`` on infos) -> type."""
    Store(tmp_path / "state.sqlite").close()
    m = ServiceMetrics("0", tmp_path / "state.sqlite")
    m.watch(jobs=lambda: {"queued": 0, "running": 0}, brokers=lambda: {"consumer": True}, lag=lambda: {"t": 0},
            loop_age=lambda: 0.0, assigned=lambda: 1)
    out = {}
    for fam in m.registry.collect():
        suffix = {"counter": "_total", "info": "_info"}.get(fam.type, "")
        out[fam.name + suffix] = "gauge" if fam.type == "info" else fam.type
    return out


def test_the_metric_table_is_what_the_daemon_exports(tmp_path: Path) -> None:
    table = _table()
    exported = _exported(tmp_path)
    assert set(table) == set(exported), (set(table) ^ set(exported))
    for name, kind in exported.items():
        assert table[name] == kind, name


def test_alert_rules_are_a_rule_file_over_documented_metrics() -> None:
    block = re.search(r"```yaml\n(groups:.*?)```", DOC.read_text(), re.DOTALL)
    assert block, "no rule file in docs/operations.md"
    rules = yaml.safe_load(block.group(1))
    (group,) = rules["groups"]
    assert group["name"] == "mushrooms" and len(group["rules"]) >= 5
    names = set(_table())
    for rule in group["rules"]:
        assert set(rule) <= {"alert", "expr", "for", "labels", "annotations"}, rule
        assert re.fullmatch(r"Mushrooms[A-Za-z]+", rule["alert"]) and rule["annotations"]["summary"]
        if "for" in rule:
            assert re.fullmatch(r"\d+[smh]", rule["for"])
        used = set(re.findall(r"\b(mushrooms_[a-z_]+?)(?:_bucket|_count|_sum)?\b", rule["expr"]))
        assert used <= names, (rule["alert"], used - names)
        assert rule["expr"].count("(") == rule["expr"].count(")")
    alerts = {r["alert"] for r in group["rules"]}
    assert {"MushroomsFirstPlanMissing", "MushroomsOutboxStuck", "MushroomsInputBrokerDown"} <= alerts
