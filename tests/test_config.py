"""config.toml documents exactly the built-in defaults; bad configs are refused clearly."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import pytest

from mushrooms.tool.config import Config, ConfigError, load_config

ROOT = Path(__file__).resolve().parents[1]


def _flatten(obj, prefix=""):
    out = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out.update(_flatten(v, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = list(v) if isinstance(v, tuple) else v
    return out


def test_config_toml_lists_every_key_with_its_default():
    data = tomllib.loads((ROOT / "config.toml").read_text())
    defaults = Config()
    for section in ("scheduler", "policy", "daemon", "kafka", "outbound", "export", "submit"):
        expected = _flatten(getattr(defaults, section))
        got = {}
        for k, v in data[section].items():
            if isinstance(v, dict):
                got.update({f"{k}.{kk}": vv for kk, vv in v.items()})
            else:
                got[k] = v
        optional_unset = {k for k, v in expected.items() if v is None}
        assert set(got) == set(expected) - optional_unset, section
        for k, v in got.items():
            assert v == expected[k], f"[{section}] {k}: file {v!r} != default {expected[k]!r}"


def test_config_toml_loads_to_the_defaults():
    cfg = load_config(ROOT / "config.toml")
    assert dataclasses.replace(cfg, source="x") == dataclasses.replace(Config(), source="x")


@pytest.mark.parametrize(
    "text, message",
    [
        ("[schedular]\n", "unknown section"),
        ("[scheduler]\nsolver = 'annealing'\n", "solver must be one of greedy, slots, blocks, hybrid, milp"),
        ("[scheduler]\nnside = 300\n", "power of 2"),
        ("[policy]\nmin_has_ns = 'high'\n", "policy"),
        ("[outbound]\nsink = 'email'\n", "sink must be directory or kafka"),
        ("this is not toml", "not valid TOML"),
        ("[scheduler]\nobjective = 'detection'\ntime_limit_s = 4.0\ndetection_time_limit_s = 4.0\n",
         "detection_time_limit_s .* must be less than time_limit_s"),
        ("[scheduler]\ndetection_max_coverage_loss = 1.5\n", "detection_max_coverage_loss = 1.5: outside its range"),
    ],
)
def test_bad_configs_are_refused_with_a_reason(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_config(path)


def test_loading_the_config_imports_no_numpy_astropy_or_healpy():
    # each layer's section type is a light leaf; the scheduler's checker (healpy, astropy) loads only when used
    import subprocess
    import sys

    code = ("import sys\n"
            "from mushrooms.tool.config import load_config\n"
            f"config = load_config({str(ROOT / 'config.toml')!r})\n"
            "assert config.scheduler.nside > 0 and config.source.endswith('config.toml')\n"
            "print(' '.join(m for m in ('numpy', 'astropy', 'healpy') if m in sys.modules))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == []


def test_the_section_tables_are_read_by_one_leaf_helper_with_typed_errors():
    from mushrooms.scheduler_core.tables import TableError
    from mushrooms.daemon.settings import DaemonConfig

    with pytest.raises(TableError) as wrong_type:
        DaemonConfig.from_mapping({"heartbeat_s": "often"})
    assert (wrong_type.value.section, wrong_type.value.key, wrong_type.value.value) == ("daemon", "heartbeat_s", "often")
    assert str(wrong_type.value) == "[daemon] heartbeat_s = 'often': expected a number, got string"
    with pytest.raises(TableError) as unknown:
        DaemonConfig.from_mapping({"heartbeats": 1})
    assert unknown.value.keys == ("heartbeats",)
    assert str(unknown.value) == "unknown [daemon] key(s): heartbeats (did you mean heartbeat_s?)"
    with pytest.raises(ConfigError, match=r"\[daemon\] heartbeat_s = 0: outside its range"):
        Config.from_mapping({"daemon": {"heartbeat_s": 0}})
