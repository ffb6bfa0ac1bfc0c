"""Every numeric setting is finite and within its documented range.

The ranges are declared once, beside each field (``mushrooms.scheduler_core.ranges``);
``docs/configuration.md`` and ``config.toml`` show the same ones, and every command that loads a
config refuses a value outside them with one line naming key, value and range, exit 2.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import subprocess
import sys
import typing
from pathlib import Path

import pytest

from mushrooms.cli import main
from mushrooms.tool.config import Config, ConfigError, load_config

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "tests" / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"
FAST = '[scheduler]\nsolver = "greedy"\nnside = 64\ntime_step_s = 600.0\n'


def sections() -> dict[str, type]:
    from mushrooms.daemon.loop_settings import LoopConfig
    from mushrooms.daemon.settings import DaemonConfig, KafkaConfig, OutboundConfig
    from mushrooms.evaluation.bench.settings import BenchConfig
    from mushrooms.handlers.policy import PolicyConfig
    from mushrooms.scheduler_core.config import PlanningConfig, SlewModel
    from mushrooms.scheduler_core.plan.exports import ExportConfig

    return {"scheduler": PlanningConfig, "scheduler.slew": SlewModel, "policy": PolicyConfig,
            "daemon": DaemonConfig, "kafka": KafkaConfig, "outbound": OutboundConfig, "export": ExportConfig,
            "loop": LoopConfig, "bench": BenchConfig}


def _numeric(hint) -> bool:
    args = [a for a in typing.get_args(hint) if a is not type(None)] if typing.get_origin(hint) in (
        typing.Union, getattr(__import__("types"), "UnionType")) else [hint]
    if typing.get_origin(hint) is tuple:
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
    return any(a in (int, float) for a in args)


def test_every_numeric_setting_declares_a_range():
    from mushrooms.scheduler_core.ranges import ranges_of

    missing = []
    for name, cls in sections().items():
        hints = typing.get_type_hints(cls)
        ranged = ranges_of(cls)
        missing += [f"[{name}] {f.name}" for f in dataclasses.fields(cls)
                    if _numeric(hints[f.name]) and f.name not in ranged]
    assert missing == []


def test_the_docs_table_is_the_declared_ranges():
    from mushrooms.scheduler_core.ranges import markdown_table

    text = (ROOT / "docs" / "configuration.md").read_text()
    assert markdown_table(sections()) in text
    assert "docs/configuration.md" in (ROOT / "README.md").read_text()


def test_config_toml_shows_each_range_beside_its_key():
    from mushrooms.scheduler_core.ranges import ranges_of

    secs = sections()
    section, seen, wrong = None, set(), []
    for line in (ROOT / "config.toml").read_text().splitlines():
        if m := re.match(r"^\[([a-z.]+)\]", line):
            section = m.group(1)
        if (m := re.match(r"^(#\s*)?([a-z_0-9]+)\s*=", line)) and section in secs:
            rng = ranges_of(secs[section]).get(m.group(2))
            if rng is not None:
                seen.add((section, m.group(2)))
                if f"# {rng}" not in line:
                    wrong.append(line)
    assert wrong == []
    expected = {(s, k) for s, c in secs.items() if s != "bench" for k in ranges_of(c)}
    assert expected - seen == set()


# the values an adversarial run tried, and a few more of the same kind
HOSTILE = [
    ("daemon", "job_deadline_s", "1e12"), ("daemon", "job_deadline_s", "inf"), ("daemon", "job_deadline_s", "nan"),
    ("scheduler", "exposure_s", "nan"), ("scheduler", "cadence_s", "nan"), ("scheduler", "airmass_max", "nan"),
    ("scheduler", "sun_alt_max_deg", "nan"), ("scheduler", "dec_min_deg", "nan"),
    ("scheduler", "time_step_s", "nan"), ("scheduler", "horizon_h", "1e-6"), ("scheduler", "nside", "1"),
    ("scheduler", "nside", "2"), ("scheduler", "nside", "4"), ("scheduler", "nside", "4096"),
    ("scheduler", "time_step_s", "0.01"), ("daemon", "heartbeat_s", "inf"), ("daemon", "max_jobs", "100000"),
    ("scheduler", "nside", "300"), ("policy", "max_far_hz", "nan"), ("policy", "max_notice_age_s", "-inf"),
    ("kafka", "session_timeout_s", "0.001"), ("outbound", "retry_max_s", "inf"), ("scheduler.slew", "settle_s", "nan"),
    ("export", "skyportal_allocation_id", "-3"), ("scheduler", "slot_positions", "[6, 0]"),
]


@pytest.mark.parametrize("section, key, value", HOSTILE, ids=[f"{s}.{k}={v}" for s, k, v in HOSTILE])
def test_a_value_outside_its_range_is_one_line_exit_2(tmp_path, capsys, section, key, value):
    cfg = tmp_path / "c.toml"
    cfg.write_text(f"[{section}]\n{key} = {value}\n")
    out = tmp_path / "plan.json"
    assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "error" in line]
    assert len(err) == 1 and f"[{section}] {key}" in err[0] and "range" in err[0], err
    assert not out.exists()


def test_a_hand_built_config_is_held_to_finite_numbers():
    from mushrooms.daemon.settings import DaemonConfig
    from mushrooms.scheduler_core.config import PlanningConfig

    for bad in (dict(exposure_s=math.nan), dict(cadence_s=math.inf), dict(slot_positions=(6, math.nan))):
        with pytest.raises(ValueError, match="not a finite number"):
            PlanningConfig(**bad)
    with pytest.raises(ValueError, match="job_deadline_s = inf"):
        DaemonConfig(job_deadline_s=math.inf)


def test_cross_key_limits_name_both_keys():
    for table, words in (({"scheduler": {"dec_min_deg": 10.0, "dec_max_deg": 0.0}}, "dec_max_deg"),
                         ({"scheduler": {"time_step_s": 10.0, "horizon_h": 168.0}}, "time_step_s"),
                         ({"outbound": {"retry_initial_s": 60.0, "retry_max_s": 5.0}}, "retry_max_s")):
        with pytest.raises(ConfigError, match=words):
            Config.from_mapping(table)


def test_the_edges_of_the_scheduler_ranges_plan(tmp_path, capsys):
    """The bounds are usable values: a plan (or a not_observable answer), never an internal error."""
    edges = ('nside = 16\nhorizon_h = 1.0\ntime_step_s = 900.0\nexposure_s = 1.0\ncadence_s = 60.0\n',
             'nside = 64\nhorizon_h = 24.0\ntime_step_s = 10.0\nairmass_max = 3.0\nsun_alt_max_deg = 0.0\n')
    for i, edge in enumerate(edges):
        cfg = tmp_path / f"e{i}.toml"
        cfg.write_text('[scheduler]\nsolver = "greedy"\n' + edge)
        out = tmp_path / f"e{i}.json"
        assert main(["plan", str(MAP), "--config", str(cfg), "-o", str(out)]) == 0, capsys.readouterr().err
        assert json.loads(out.read_text())["type"] in ("plan", "not_observable")


@pytest.mark.parametrize("command", ["plan", "check", "replay", "trigger", "bench", "demo", "run"])
def test_every_command_refuses_a_bad_config_before_it_starts(tmp_path, command):
    """``run`` included: a daemon with ``job_deadline_s = 1e12`` once consumed and heartbeated but never planned."""
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[daemon]\njob_deadline_s = 1e12\n")
    args = {"plan": [str(MAP)], "check": [str(tmp_path / "p.json"), str(MAP)], "replay": [str(tmp_path)],
            "trigger": ["S250101ab", "--state", str(tmp_path / "s.sqlite")], "bench": [str(tmp_path)],
            "demo": ["--out", str(tmp_path / "demo")],
            "run": ["--bootstrap", "127.0.0.1:9", "--state", str(tmp_path / "s.sqlite")]}[command]
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    r = subprocess.run([sys.executable, "-m", "mushrooms.cli", command, *args, "--config", str(cfg)],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    errors = [line for line in r.stderr.splitlines() if "error" in line]
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(errors) == 1 and "[daemon] job_deadline_s = 1e+12: outside its range [1, 86400] s" in errors[0]
    assert not (tmp_path / "s.sqlite").exists() and not (tmp_path / "demo").exists()


def test_the_shipped_config_loads_and_equals_the_defaults():
    loaded = load_config(ROOT / "config.toml")
    assert dataclasses.replace(loaded, source=Config().source) == Config()


def test_no_document_the_service_writes_holds_nan(tmp_path):
    from mushrooms.daemon.sinks import DirectorySink
    from mushrooms.outputs import write_json_atomic
    from mushrooms.scheduler_core.plan import strict_json

    doc = {"type": "plan", "plan_id": "p", "metrics": {"coverage": 0.5, "mip_gap": [0.0, math.nan]}}
    with pytest.raises(ValueError, match=r"NaN or infinity at metrics.mip_gap\[1\]"):
        strict_json.dumps(doc)
    with pytest.raises(ValueError, match="metrics.mip_gap"):
        write_json_atomic(tmp_path / "p.json", doc)
    assert not (tmp_path / "p.json").exists()
    sink = DirectorySink(tmp_path / "outbox")
    with pytest.raises(ValueError, match="NaN or infinity"):
        sink.publish(doc)
    assert json.loads(strict_json.dumps({"a": 1.5})) == {"a": 1.5}
