"""Read ``config.toml`` into typed sections; every key has an embedded default.

Sections: ``[scheduler]`` (:class:`~mushrooms.scheduler_core.PlanningConfig`),
``[policy]`` (:class:`~mushrooms.handlers.policy.PolicyConfig`),
``[daemon]``, ``[kafka]``, ``[outbound]`` (:mod:`mushrooms.daemon.settings`),
``[export]`` (:class:`~mushrooms.scheduler_core.exports.ExportConfig`);
an optional ``[bench]`` table is read by ``mushrooms bench`` only.
Secrets never come from here: see the README.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .daemon.settings import DaemonConfig, KafkaConfig, OutboundConfig
from .handlers.policy import PolicyConfig
from .scheduler_core.config import PlanningConfig
from .scheduler_core.exports import ExportConfig

__all__ = ["Config", "ConfigError", "load_config"]


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
        }
        # [bench] belongs to `mushrooms bench`, which reads it itself
        unknown = sorted(set(data) - set(sections) - {"bench"})
        if unknown:
            raise ConfigError(f"{source}: unknown section(s): {', '.join(unknown)}")
        kwargs: dict[str, Any] = {"source": source}
        try:
            for name, cls_ in sections.items():
                if name in data:
                    kwargs[name] = cls_.from_mapping(data[name])
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{source}: {exc}") from None
        return cls(**kwargs)


def load_config(path: str | Path | None = None) -> Config:
    """Load a config file, or the embedded defaults when ``path`` is None.

    Raises
    ------
    ConfigError
        With a one-line reason when the file cannot be used.
    """
    if path is None:
        return Config()
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read config {p}: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    return Config.from_mapping(data, source=str(p))
