"""Settings of the service: the ``[daemon]``, ``[kafka]`` and ``[outbound]`` tables."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

__all__ = ["DaemonConfig", "KafkaConfig", "OutboundConfig"]


def _from_table(cls: type, table: Mapping[str, Any], name: str) -> Any:
    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - known)
    if unknown:
        raise ValueError(f"unknown [{name}] key(s): {', '.join(unknown)}")
    values = dict(table)
    for f in dataclasses.fields(cls):
        if f.name in values and isinstance(values[f.name], list):
            values[f.name] = tuple(values[f.name])
    return cls(**values)


@dataclass(frozen=True)
class DaemonConfig:
    """Where the service keeps its state and how it paces itself.

    Attributes
    ----------
    state_path : str
        SQLite file (WAL) with notices, decisions, jobs, plans and outbox.
        Relative paths are taken from the working directory; under systemd
        the unit's StateDirectory is used.
    trigger_dir : str
        Directory where ``mushrooms trigger`` drops work for the daemon.
    pid_file : str
        File holding the running daemon's pid (for SIGUSR1).
    heartbeat_s : float
        Interval (s) of the heartbeat log line and systemd watchdog ping.
    """

    state_path: str = "mushrooms-state.sqlite"
    trigger_dir: str = "mushrooms-triggers"
    pid_file: str = "mushrooms.pid"
    heartbeat_s: float = 30.0

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "DaemonConfig":
        return _from_table(cls, table, "daemon")


@dataclass(frozen=True)
class KafkaConfig:
    """GCN Kafka input.  Credentials never live here: see README.

    Attributes
    ----------
    topics : tuple of str
        Input topics.
    group_id : str
        Fixed consumer group id.
    domain : str
        GCN Kafka domain (gcn.nasa.gov for production).
    bootstrap : str
        If set, connect to this broker in plaintext with no credentials
        (local broker for tests and development) instead of GCN.
    poll_timeout_s : float
        ``consume()`` timeout (s); keeps signals responsive.
    """

    topics: tuple[str, ...] = ("igwn.gwalert",)
    group_id: str = "mushrooms-ztf"
    domain: str = "gcn.nasa.gov"
    bootstrap: str = ""
    poll_timeout_s: float = 1.0

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "KafkaConfig":
        return _from_table(cls, table, "kafka")


@dataclass(frozen=True)
class OutboundConfig:
    """Where plans and withdrawals go.

    Attributes
    ----------
    sink : str
        ``directory`` (default: atomic JSON files) or ``kafka``.
    directory : str
        Output directory of the directory sink.
    topic : str
        Output topic of the Kafka sink.
    bootstrap : str
        Broker of the Kafka sink (defaults to the input broker).
    retry_initial_s, retry_max_s : float
        Back-off (s) for failed publishes.
    """

    sink: str = "directory"
    directory: str = "mushrooms-outbox"
    topic: str = "mushrooms.plans"
    bootstrap: str = ""
    retry_initial_s: float = 2.0
    retry_max_s: float = 300.0

    def __post_init__(self) -> None:
        if self.sink not in ("directory", "kafka"):
            raise ValueError(f"[outbound] sink must be directory or kafka, got {self.sink!r}")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "OutboundConfig":
        return _from_table(cls, table, "outbound")
