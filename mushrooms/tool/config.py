"""Read ``config.toml`` into typed sections; every key has an embedded default.

Sections: ``[scheduler]`` (:class:`~mushrooms.scheduler_core.PlanningConfig`),
``[policy]`` (:class:`~mushrooms.handlers.policy.PolicyConfig`),
``[daemon]``, ``[kafka]``, ``[outbound]`` (:mod:`mushrooms.daemon.settings`),
``[export]`` (:class:`~mushrooms.scheduler_core.plan.exports.ExportConfig`),
``[submit]`` (:class:`~mushrooms.daemon.submission.settings.SubmitConfig`),
``[loop]`` (:class:`~mushrooms.daemon.loop_settings.LoopConfig`),
``[notify]`` (:class:`~mushrooms.daemon.ops.webhook_settings.NotifyConfig`),
``[bench]`` (:class:`~mushrooms.evaluation.bench.settings.BenchConfig`:
``mushrooms bench`` and ``mushrooms study``).
Secrets never come from here: see the README.

Each layer owns its section types (built on the leaf
:mod:`mushrooms.scheduler_core.tables`); this module, in the tool layer,
assembles them.  Only :mod:`mushrooms.tool` and :mod:`mushrooms.cli` import
it (``tests/test_architecture.py``): the daemon is handed the sections.
Reading a file imports no numpy, astropy or healpy.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from ..daemon.settings import DaemonConfig, KafkaConfig, OutboundConfig
from ..daemon.loop_settings import LoopConfig
from ..daemon.submission.settings import SubmitConfig
from ..daemon.submission.parts_settings import PartSubmitConfig
from ..daemon.ops.webhook_settings import NotifyConfig
from ..evaluation.bench.settings import BenchConfig
from ..handlers.policy import PolicyConfig
from ..scheduler_core.config import PlanningConfig
from ..scheduler_core.plan.exports import ExportConfig

__all__ = ["Config", "ConfigError", "load_config", "read_config_table", "resolve_config_path", "CONFIG_ENV"]

#: Environment variable naming the config file when ``--config`` is not given.
CONFIG_ENV = "MUSHROOMS_CONFIG"

#: Largest config file read (bytes); the documented one is 10 KB.
MAX_CONFIG_BYTES = 1024 * 1024


class ConfigError(ValueError):
    """The configuration file is missing, unreadable or invalid."""


@dataclass(frozen=True)
class Config:
    """The whole configuration."""

    scheduler: PlanningConfig = field(default_factory=PlanningConfig)
    policy: PolicyConfig = field(default_factory=PolicyConfig)
    daemon: DaemonConfig = field(default_factory=DaemonConfig)
    kafka: KafkaConfig = field(default_factory=KafkaConfig)
    outbound: OutboundConfig = field(default_factory=OutboundConfig)
    source: str = "<embedded defaults>"
    export: ExportConfig = field(default_factory=ExportConfig)
    submit: SubmitConfig = field(default_factory=SubmitConfig)
    bench: BenchConfig = field(default_factory=BenchConfig)
    loop: LoopConfig = field(default_factory=LoopConfig)
    notify: NotifyConfig = field(default_factory=NotifyConfig)
    submit_parts: PartSubmitConfig = field(default_factory=PartSubmitConfig)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "<mapping>") -> "Config":
        """Build from parsed TOML; unknown sections or keys are errors."""
        sections = {
            "scheduler": PlanningConfig,
            "policy": PolicyConfig,
            "daemon": DaemonConfig,
            "kafka": KafkaConfig,
            "outbound": OutboundConfig,
            "export": ExportConfig,
            "submit": SubmitConfig,
            "bench": BenchConfig,
            "loop": LoopConfig,
            "notify": NotifyConfig,
            "submit_parts": PartSubmitConfig,
        }
        from ..scheduler_core.tables import TableError, shown_value, toml_type, unknown_names

        unknown = sorted(set(data) - set(sections))
        if unknown:
            raise ConfigError(f"{source}: unknown section(s): {unknown_names(unknown, list(sections))}")
        kwargs: dict[str, Any] = {"source": source}
        try:
            for name, cls_ in sections.items():
                if name not in data:
                    continue
                if not isinstance(data[name], Mapping):  # `scheduler = 1` at the top of the file
                    raise TableError(f"{name} = {shown_value(data[name])}: expected a table ([{name}]), got "
                                     f"{toml_type(data[name])}", section=name, value=data[name], expected="a table")
                kwargs[name] = cls_.from_mapping(data[name])
            if "scheduler" in kwargs:
                _check_lightcurve(kwargs["scheduler"].detection_lightcurve)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{source}: {exc}") from None
        return cls(**kwargs)


#: Largest light-curve file read at load (bytes); the packaged ones are 10-20 KB.
MAX_LIGHTCURVE_BYTES = 16 * 1024 * 1024


def _check_lightcurve(spec: str) -> None:
    """A ``detection_lightcurve`` file must parse now, not in every job (each of which would be ``rejected``).

    The packaged names are not read; a file is (numpy is imported only then).

    Raises
    ------
    ValueError
        ``[scheduler] detection_lightcurve = '...': <why>``.
    """
    from ..scheduler_core.lightcurve_names import PAPER_LIGHTCURVES

    if spec in PAPER_LIGHTCURVES:
        return
    from ..inputs import read_regular_file
    from ..scheduler_core.errors import InputError
    from ..scheduler_core.source.lightcurves import parse_lightcurve

    try:
        text = read_regular_file(spec, MAX_LIGHTCURVE_BYTES, what="light curve").decode()
        parse_lightcurve(text, name=Path(spec).stem)
    except (InputError, UnicodeDecodeError) as exc:
        why = "not UTF-8 text" if isinstance(exc, UnicodeDecodeError) else str(exc)
        raise ValueError(f"[scheduler] detection_lightcurve = {spec!r}: {why}") from None


def resolve_config_path(given: str | Path | None, environ: Mapping[str, str] | None = None,
                        cwd: Path | None = None) -> tuple[Path | None, str]:
    """Which config file a command uses, by one rule, first match wins.

    1. ``--config FILE`` when given;
    2. else ``$MUSHROOMS_CONFIG`` when set and not empty;
    3. else ``./config.toml`` when the working directory has one;
    4. else the embedded defaults (None).

    Returns
    -------
    path : pathlib.Path or None
    why : str
        Which rule chose it (for the log).
    """
    import os

    env = os.environ if environ is None else environ
    if given:
        return Path(given), "--config"
    if env.get(CONFIG_ENV, "").strip():
        return Path(env[CONFIG_ENV].strip()), f"${CONFIG_ENV}"
    local = (cwd or Path.cwd()) / "config.toml"
    if local.is_file():
        return local, "config.toml in the working directory"
    return None, "no --config, no $MUSHROOMS_CONFIG, no ./config.toml"


def load_config(path: str | Path | None = None, sets: Any = ()) -> Config:
    """Load a config file, or the embedded defaults when ``path`` is None; ``sets`` are ``--set`` overrides.

    Raises
    ------
    ConfigError
        With a one-line reason when the file cannot be used, or a ``--set`` is malformed or out of range.
    """
    if not sets:
        if path is None:
            return Config()
        return Config.from_mapping(read_config_table(path), source=str(path))
    from .settings_flag import apply_sets

    try:
        table = apply_sets({} if path is None else read_config_table(path), sets)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    shown = " ".join(s if len(s) <= 80 else s[:77] + "..." for s in sets)  # a hostile --set: one short line
    return Config.from_mapping(table, source=f"{path or '<embedded defaults>'} with --set {shown}")


def read_config_table(path: str | Path) -> dict[str, Any]:
    """The parsed TOML of a config file (a regular file: :mod:`mushrooms.inputs`), sections unchecked.

    Raises
    ------
    ConfigError
        When the file cannot be read or is not TOML.
    """
    from ..inputs import read_regular_file
    from ..scheduler_core.errors import InputError

    p = Path(path)
    try:
        text = read_regular_file(p, MAX_CONFIG_BYTES).decode()
    except InputError as exc:
        raise ConfigError(f"cannot read config {exc}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{p}: not valid TOML: not UTF-8 text") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
