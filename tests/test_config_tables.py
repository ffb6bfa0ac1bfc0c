"""A value that is not a table where a table belongs is refused at load, by every command, in one line.

``[scheduler] slew = 1`` once passed validation: the service started, its
warm-up plan failed with a mere WARNING, readiness was green and every job
failed with ``AttributeError`` (``mushrooms plan`` exited 70).  Here every
table-valued key of every section, found from the types of the embedded
defaults (a nested dataclass or a mapping), is given each kind of TOML value
that is not a table (integer, float, boolean, string, array), in the file and
by ``--set``: each is one line naming the key, exit 2, before any work.  The
sections themselves are tables too (``scheduler = 1`` at the top of a file).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path

import pytest

from mushrooms.cli import main
from mushrooms.tool.config import Config, ConfigError, load_config

DATA = Path(__file__).resolve().parent / "data"
MAP = DATA / "skymaps" / "MS220722v_bayestar.multiorder.fits"

#: One TOML literal of each kind that is not a table.
NOT_TABLES = {"integer": "1", "float": "2.5", "boolean": "true", "string": '"fast"', "array": "[1, 2]"}


def _table_valued(obj: object, prefix: str) -> list[str]:
    """Dotted names of the keys of a section whose default is a table (a dataclass or a mapping), nested too."""
    out = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            out.append(f"{prefix}.{f.name}")
            out += _table_valued(value, f"{prefix}.{f.name}")
        elif isinstance(value, Mapping):
            out.append(f"{prefix}.{f.name}")
    return out


def _sections() -> list[str]:
    defaults = Config()
    return [f.name for f in dataclasses.fields(defaults) if dataclasses.is_dataclass(getattr(defaults, f.name))]


#: Every table-valued key, plus an arm of ``[bench.arms]`` (a table of tables with names of the user's).
TABLE_KEYS = [key for s in _sections() for key in _table_valued(getattr(Config(), s), s)] + ["bench.arms.quick"]


def _file_text(dotted: str, literal: str) -> str:
    *tables, key = dotted.split(".")
    return f"[{'.'.join(tables)}]\n{key} = {literal}\n"


def test_the_loader_takes_as_tables_exactly_the_keys_whose_defaults_are_tables():
    # the discovery is not vacuous: the one that failed every job and the bench's tables are among them
    assert {"scheduler.slew", "bench.lightcurves", "bench.maglim", "bench.arms"} <= set(TABLE_KEYS)
    import typing

    from mushrooms.scheduler_core.tables import is_table_hint

    def hinted(cls: type, prefix: str) -> list[str]:
        out = []
        for name, hint in typing.get_type_hints(cls).items():
            if name in {f.name for f in dataclasses.fields(cls)} and is_table_hint(hint):
                out.append(f"{prefix}.{name}")
                if dataclasses.is_dataclass(hint):
                    out += hinted(hint, f"{prefix}.{name}")
        return out

    by_type = [key for s in _sections() for key in hinted(type(getattr(Config(), s)), s)]
    assert sorted(by_type) == sorted(TABLE_KEYS[:-1])  # the arm is a name of the user's, not a field


@pytest.mark.parametrize("kind", NOT_TABLES)
@pytest.mark.parametrize("dotted", TABLE_KEYS)
def test_a_value_that_is_not_a_table_where_one_belongs_is_refused_in_the_file_and_by_set(tmp_path, dotted, kind):
    literal = NOT_TABLES[kind]
    section, *inner = dotted.split(".")
    where = f"[{section}] {'.'.join(inner)} = "  # as every message names a key: `[bench] maglim.g = 40`
    cfg = tmp_path / "config.toml"
    cfg.write_text(_file_text(dotted, literal))
    for load in (lambda: load_config(cfg), lambda: load_config(None, [f"{dotted}={literal}"])):
        with pytest.raises(ConfigError) as refused:
            load()
        message = str(refused.value)
        assert where in message and "expected a table" in message and f"got {kind}" in message, message
        assert "\n" not in message


@pytest.mark.parametrize("kind", NOT_TABLES)
@pytest.mark.parametrize("dotted", TABLE_KEYS)
def test_plan_refuses_it_with_one_line_and_exit_2_before_any_work(tmp_path, capsys, dotted, kind):
    literal = NOT_TABLES[kind]
    cfg = tmp_path / "config.toml"
    cfg.write_text(_file_text(dotted, literal))
    out = tmp_path / "p.json"
    for extra in (["--config", str(cfg)], ["--set", f"{dotted}={literal}"]):
        assert main(["plan", str(MAP), "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("mushrooms plan: error: ") and "expected a table" in err, err
        assert not out.exists()


@pytest.mark.parametrize("kind", NOT_TABLES)
@pytest.mark.parametrize("section", _sections())
def test_a_section_that_is_not_a_table_is_refused(tmp_path, section, kind):
    cfg = tmp_path / "config.toml"
    cfg.write_text(f"{section} = {NOT_TABLES[kind]}\n")
    with pytest.raises(ConfigError) as refused:
        load_config(cfg)
    assert f"[{section}]" in str(refused.value) and "expected a table" in str(refused.value), str(refused.value)


def test_the_service_refuses_it_at_start_with_one_line_and_exit_2(tmp_path):
    # `mushrooms run` (what systemd starts): exit 2 is in the unit's RestartPreventExitStatus
    import os
    import subprocess
    import sys

    state = tmp_path / "state.sqlite"
    env = {k: v for k, v in os.environ.items() if k != "MUSHROOMS_CONFIG"}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])  # this checkout's mushrooms
    r = subprocess.run([sys.executable, "-m", "mushrooms.cli", "--log-level", "WARNING", "run", "--set",
                        "scheduler.slew=1", "--state", str(state), "--bootstrap", "127.0.0.1:9"],
                       capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)  # hang guard only
    assert r.returncode == 2, r.stderr[-2000:]
    assert r.stderr == ("mushrooms run: error: <embedded defaults> with --set scheduler.slew=1: [scheduler] slew = 1: "
                        "expected a table ([scheduler.slew] with the keys ha_accel_deg_s2, ha_vmax_deg_s, "
                        "dec_accel_deg_s2, dec_vmax_deg_s, settle_s, readout_s), got integer\n")
    assert not state.exists()


def test_set_into_a_table_the_file_gives_as_a_scalar_is_refused(tmp_path):
    # the file's `slew = 1` must not be silently replaced by a table made of one --set key
    cfg = tmp_path / "config.toml"
    cfg.write_text("[scheduler]\nslew = 1\n")
    with pytest.raises(ConfigError, match=r"--set scheduler\.slew\.readout_s=9: scheduler\.slew is not a table"):
        load_config(cfg, ["scheduler.slew.readout_s=9"])


def test_a_hand_built_planning_config_with_a_slew_that_is_not_a_slew_model_is_refused():
    from mushrooms.scheduler_core import PlanningConfig

    with pytest.raises(ValueError, match=r"\[scheduler\] slew must be a SlewModel"):
        PlanningConfig(slew=1)


@pytest.mark.parametrize("text, sets, said", [
    ("[scheduler]\nslwe = 1\n", (), "unknown [scheduler] key(s): slwe (did you mean slew?)"),
    ("[schedular]\nsolver = \"greedy\"\n", (), "unknown section(s): schedular (did you mean scheduler?)"),
    ("", ("scheduler.time_limit=4",), "unknown [scheduler] key(s): time_limit (did you mean time_limit_s?)"),
    ("", ("scheduler.slew.readot_s=9",), "unknown [scheduler.slew] key(s): readot_s (did you mean readout_s?)"),
    ("[daemon]\nheartbeats = 1\nzzz = 2\n", (),
     "unknown [daemon] key(s): heartbeats (did you mean heartbeat_s?), zzz"),
])
def test_a_mistyped_key_or_section_gets_a_did_you_mean(tmp_path, text, sets, said):
    cfg = tmp_path / "config.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError) as refused:
        load_config(cfg, list(sets))
    assert str(refused.value).endswith(said), str(refused.value)


@pytest.mark.parametrize("text, said", [
    ("[scheduler]\nfilters = [1, 2]\n", "[scheduler] filters = [1, 2]: expected an array of strings, got array"),
    ("[scheduler]\nslot_positions = [\"a\"]\n", "expected an array of integers, got array"),
    ("[scheduler]\nexposure_menu_s = [true]\n", "expected an array of numbers, got array"),
])
def test_the_type_of_an_array_is_said_in_plain_english(tmp_path, text, said):
    cfg = tmp_path / "config.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError) as refused:
        load_config(cfg)
    assert said in str(refused.value) and " a strings" not in str(refused.value)


@pytest.mark.parametrize("content, why", [(b"garbage\n", "first line must be a header"),
                                          (b"# t[days] g r\n0.1 -15 x\n", "non-numeric value"),
                                          (b"\xff\xfe\n", "not UTF-8 text")])
def test_a_light_curve_file_that_does_not_parse_is_refused_at_load_not_in_every_job(tmp_path, content, why):
    # it passed validation (the file exists) and every job was then `rejected`, blaming the notice
    curve = tmp_path / "curve.txt"
    curve.write_bytes(content)
    cfg = tmp_path / "config.toml"
    cfg.write_text(f'[scheduler]\ndetection_lightcurve = "{curve}"\n')
    for load in (lambda: load_config(cfg), lambda: load_config(None, [f'scheduler.detection_lightcurve="{curve}"'])):
        with pytest.raises(ConfigError) as refused:
            load()
        assert f"[scheduler] detection_lightcurve = '{curve}': " in str(refused.value) and why in str(refused.value)
        assert "\n" not in str(refused.value)
    curve.write_text("# t[days] g r\n0.1 -15.0 -15.5\n1.0 -14.0 -14.8\n")  # one that parses is taken
    assert load_config(cfg).scheduler.detection_lightcurve == str(curve)


def test_a_hostile_set_is_refused_in_one_short_line():
    # a 100 kB key, a 100 000-element array where a table belongs, 30 unknown keys: each one short line
    for sets in (["scheduler." + "k" * 100_000 + "=1"], ["scheduler.slew=[" + ",".join(["1"] * 100_000) + "]"],
                 [f"scheduler.zz{i}=1" for i in range(30)]):
        with pytest.raises(ConfigError) as refused:
            load_config(None, sets)
        assert len(str(refused.value)) < 1000 and "\n" not in str(refused.value), str(refused.value)[:300]
