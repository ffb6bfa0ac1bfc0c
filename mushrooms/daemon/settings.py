"""Settings of the service: the ``[daemon]``, ``[kafka]`` and ``[outbound]`` tables."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from ..scheduler_core.tables import dataclass_from_table
from ..scheduler_core.ranges import require_finite, setting

__all__ = ["DaemonConfig", "KafkaConfig", "OutboundConfig", "RuntimePaths", "resolve_paths", "parse_address",
           "group_instance_id"]


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:9464`` for IPv6) as (host, port); raises ValueError."""
    host, sep, port = text.strip().rpartition(":")
    if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"[daemon] metrics_address must be HOST:PORT, got {text!r}")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    return host or "0.0.0.0", int(port)


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
        Interval (s) of the heartbeat log line and systemd status update.
        The watchdog is pinged at half of systemd's ``WatchdogSec``.
    max_jobs : int
        Planning jobs (different superevents) that run at the same time.
    job_deadline_s : float
        A planning job still running this long (s) after it started is asked
        to stop (the scheduler then returns its best plan so far).
    quarantine_dir : str
        Where a received message that cannot be stored after repeated
        attempts is written (raw bytes) before its offset is committed, so
        that nothing received is lost and one bad message never blocks the
        stream.
    accept_retries : int
        Attempts to store a received message before it is quarantined.
    stop_grace_s : float
        After SIGTERM, running planning jobs may finish within this time (s);
        a job still running then stays pending in the store and resumes at
        the next start.  Keep it below the unit's ``TimeoutStopSec``.
    supersede_min_gain : float
        Every job publishes the fast (greedy) plan at once as revision 1; the
        configured solver's plan replaces it (revision 2) only when it covers
        at least this much more probability (absolute, 0-1).  Default 0.005:
        more than twice the 0.002 by which the plan checker's and the
        schedulers' footprints may disagree, so a replacement is never
        noise, yet small enough that a real improvement (typically 0.01-0.05
        on the shared maps) always goes out.  Replacing a queued plan costs
        the observers a reload.  With ``[scheduler] objective =
        "detection"`` the margin applies to ``metrics.expected_detections``
        instead (the probability of detecting the kilonova, also 0-1),
        and revision 2 must also respect the coverage floor
        ``detection_max_coverage_loss`` against revision 1; when the
        expected detections tie within the margin (both ~0 for a source
        too far for the light curve) coverage decides by the margin
        (rules R1-R3 of ``docs/design/detection.md``,
        :func:`~mushrooms.scheduler_core.anytime.is_better`).
    group_readable : bool
        Create the state file 0640 and the service's directories 0750
        (readable by the service's group, e.g. for backups or monitoring)
        instead of 0600 and 0700.
    rejected_raw_retention_s : float
        How long (s) the first KiB of a rejected message is kept for
        inspection; then only its SHA-256, size and decision remain.
    metrics_address : str
        ``HOST:PORT`` of the HTTP listener with ``/metrics`` (Prometheus),
        ``/healthz`` and ``/readyz`` (docs/operations.md), e.g.
        ``127.0.0.1:9464``; empty (default): no listener.
    planned_raw_retention_s : float
        How long (s) after its last job finished the raw bytes of an
        event's newest planned notice are kept (``mushrooms trigger
        SUPEREVENT`` re-plans from them).  Older notices of the event lose
        theirs as soon as none of their jobs is open; the notice row, its
        SHA-256, size and decisions stay.  Default 7 days.
    """

    state_path: str = "mushrooms-state.sqlite"
    trigger_dir: str = "mushrooms-triggers"
    pid_file: str = "mushrooms.pid"
    heartbeat_s: float = setting(30.0, 1, 600, "s", why="systemd's status and the log line; the watchdog has its own clock")
    max_jobs: int = setting(2, 1, 32, why="each job is a solver on a core")
    job_deadline_s: float = setting(300.0, 1, 86400, "s", why="an alert's plan is due within minutes; a day at most")
    quarantine_dir: str = "mushrooms-quarantine"
    accept_retries: int = setting(3, 1, 100)
    stop_grace_s: float = setting(20.0, 0, 600, "s", why="below the unit's TimeoutStopSec")
    supersede_min_gain: float = setting(0.005, 0, 1, why="probability")
    group_readable: bool = False
    rejected_raw_retention_s: float = setting(2_592_000.0, 0, 31_622_400, "s", why="up to a year")
    planned_raw_retention_s: float = setting(604_800.0, 0, 31_622_400, "s", why="up to a year")

    metrics_address: str = ""

    def __post_init__(self) -> None:
        require_finite(self, "daemon")
        if self.metrics_address:
            parse_address(self.metrics_address)
        if not 0.0 <= self.supersede_min_gain <= 1.0:
            raise ValueError(f"[daemon] supersede_min_gain must be within 0-1, got {self.supersede_min_gain}")
        if self.max_jobs < 1:
            raise ValueError(f"[daemon] max_jobs must be >= 1, got {self.max_jobs}")
        if self.heartbeat_s <= 0 or self.job_deadline_s <= 0:
            raise ValueError("[daemon] heartbeat_s and job_deadline_s must be > 0")
        if self.accept_retries < 1:
            raise ValueError(f"[daemon] accept_retries must be >= 1, got {self.accept_retries}")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "DaemonConfig":
        return dataclass_from_table(cls, table, "daemon")


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
    assignment : str
        ``group`` (default: subscribe, the broker balances partitions) or
        ``manual`` (assign every partition of the topics and resume from the
        group's committed offsets; no group join, so a restart after a crash
        resumes at once; for a single consumer instance only).
    session_timeout_s : float
        Group session timeout (s): how soon a crashed member's partitions
        are handed to the restarted process in ``group`` mode.
    max_message_bytes : int
        Largest notice (bytes) the consumer fetches (a notice with its
        base64 sky map is 1-2 MB).
    offset_reset : str
        Where a group with no committed offset starts: ``earliest`` or
        ``latest``.
    instance_id : str
        Static group membership (Kafka's ``group.instance.id``, KIP-345) in
        ``group`` mode: a daemon restarted after a crash rejoins as the same
        member and gets its partitions back at once instead of waiting
        ``session_timeout_s`` for the dead member to expire.  Empty
        (default): derived from the host name and the state file's path
        (:func:`group_instance_id`), so it is stable per installation and
        differs between installations sharing a group.  ``"none"``:
        dynamic membership.  Two daemons must never share one.
    """

    topics: tuple[str, ...] = ("igwn.gwalert",)
    group_id: str = "mushrooms-ztf"
    domain: str = "gcn.nasa.gov"
    bootstrap: str = ""
    poll_timeout_s: float = setting(1.0, 0, 10, "s", lo_open=True, why="signals are handled between polls")
    assignment: str = "group"
    session_timeout_s: float = setting(30.0, 6, 300, "s", why="what a broker accepts by default (group.min/max.session.timeout.ms)")
    max_message_bytes: int = setting(16_000_000, 1_000_000, 536_870_912, "bytes", why="a notice with its map is 1-2 MB")
    offset_reset: str = "earliest"
    instance_id: str = ""

    def __post_init__(self) -> None:
        require_finite(self, "kafka")
        if self.instance_id and (len(self.instance_id) > 200 or not self.instance_id.isprintable()
                                 or " " in self.instance_id):
            raise ValueError(f"[kafka] instance_id must be printable, without spaces, at most 200 characters, "
                             f"got {self.instance_id!r}")
        if self.assignment not in ("group", "manual"):
            raise ValueError(f"[kafka] assignment must be group or manual, got {self.assignment!r}")
        if self.offset_reset not in ("earliest", "latest"):
            raise ValueError(f"[kafka] offset_reset must be earliest or latest, got {self.offset_reset!r}")
        if not self.topics:
            raise ValueError("[kafka] topics must not be empty")
        if not 0 < self.poll_timeout_s <= 10:
            raise ValueError(f"[kafka] poll_timeout_s must be in (0, 10], got {self.poll_timeout_s}")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "KafkaConfig":
        return dataclass_from_table(cls, table, "kafka")


SECURITY_PROTOCOLS = ("plaintext", "ssl", "sasl_plaintext", "sasl_ssl")
SASL_MECHANISMS = ("SCRAM-SHA-512", "SCRAM-SHA-256", "PLAIN")


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
        Broker of the Kafka sink; needed with ``sink = "kafka"``.  A local
        input broker (``[kafka] bootstrap``, ``--bootstrap``) stands in for
        it when empty; with GCN as input an empty one is refused at load
        (``mushrooms.tool.overrides.require_sink_broker``).
    retry_initial_s, retry_max_s : float
        Back-off (s) for failed publishes.
    max_message_bytes : int
        Largest plan message (bytes) the Kafka producer sends.
    delivery_timeout_s : float
        How long (s) the Kafka sink waits for the broker's acknowledgement
        before the publish counts as failed (and is retried from the outbox).
    security_protocol : str
        Kafka sink's ``security.protocol``: ``plaintext`` (default), ``ssl``,
        ``sasl_plaintext`` or ``sasl_ssl``.
    sasl_mechanism : str
        SASL mechanism for the ``sasl_*`` protocols (``SCRAM-SHA-512``,
        ``SCRAM-SHA-256`` or ``PLAIN``).
    sasl_username : str
        SASL user name (not secret).  The password never comes from the
        config: systemd credential ``outbound_password`` or the environment
        variable ``MUSHROOMS_OUTBOUND_PASSWORD``.
    """

    sink: str = "directory"
    directory: str = "mushrooms-outbox"
    topic: str = "mushrooms.plans"
    bootstrap: str = ""
    retry_initial_s: float = setting(2.0, 0.1, 3600, "s", why="at most retry_max_s")
    retry_max_s: float = setting(300.0, 0.1, 86400, "s")
    max_message_bytes: int = setting(16_000_000, 1_000_000, 536_870_912, "bytes", why="librdkafka's message.max.bytes stops at 1e9")
    delivery_timeout_s: float = setting(30.0, 1, 3600, "s")
    security_protocol: str = "plaintext"
    sasl_mechanism: str = "SCRAM-SHA-512"
    sasl_username: str = ""

    def __post_init__(self) -> None:
        require_finite(self, "outbound")
        if self.retry_initial_s > self.retry_max_s:
            raise ValueError(f"[outbound] retry_initial_s ({self.retry_initial_s:g} s) must not exceed "
                             f"retry_max_s ({self.retry_max_s:g} s)")
        if self.sink not in ("directory", "kafka"):
            raise ValueError(f"[outbound] sink must be directory or kafka, got {self.sink!r}")
        if self.security_protocol.lower() not in SECURITY_PROTOCOLS:
            raise ValueError(f"[outbound] security_protocol must be one of {', '.join(SECURITY_PROTOCOLS)}, "
                             f"got {self.security_protocol!r}")
        if self.sasl_mechanism.upper() not in SASL_MECHANISMS:
            raise ValueError(f"[outbound] sasl_mechanism must be one of {', '.join(SASL_MECHANISMS)}, "
                             f"got {self.sasl_mechanism!r}")

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "OutboundConfig":
        return dataclass_from_table(cls, table, "outbound")


@dataclass(frozen=True)
class RuntimePaths:
    """Absolute paths of the service's files, resolved once at start.

    Attributes
    ----------
    state : Path
        SQLite state file.
    trigger_dir : Path
        Drop directory of ``mushrooms trigger``.
    pid_file : Path
        Pid (and lock) file of the running daemon.
    quarantine_dir : Path
        Raw messages that could not be stored.
    """

    state: Path
    trigger_dir: Path
    pid_file: Path
    quarantine_dir: Path


def resolve_paths(daemon: DaemonConfig, environ: Mapping[str, str] | None = None) -> RuntimePaths:
    """Resolve the ``[daemon]`` paths.

    A relative ``state_path`` is taken from ``$STATE_DIRECTORY`` (set by
    systemd's ``StateDirectory=``) when present, else from the working
    directory.  Relative ``trigger_dir``, ``pid_file`` and ``quarantine_dir``
    are taken from the state file's directory, so that ``mushrooms run
    --state X`` and ``mushrooms trigger --state X`` always meet.
    """
    env = os.environ if environ is None else environ
    state = Path(daemon.state_path).expanduser()
    if not state.is_absolute():
        base = env.get("STATE_DIRECTORY", "").split(":")[0]
        state = (Path(base) if base else Path.cwd()) / state
    home = state.parent

    def near(p: str) -> Path:
        q = Path(p).expanduser()
        return q if q.is_absolute() else home / q

    return RuntimePaths(
        state=state,
        trigger_dir=near(daemon.trigger_dir),
        pid_file=near(daemon.pid_file),
        quarantine_dir=near(daemon.quarantine_dir),
    )


def group_instance_id(config: KafkaConfig, state: Path, host: str | None = None) -> str | None:
    """The consumer's ``group.instance.id``: ``[kafka] instance_id``, else one derived from the installation.

    Derived: ``mushrooms-<host>-<12 hex digits of the SHA-256 of the state
    file's absolute path>``, the same at every restart of one installation.
    None when static membership is off (``instance_id = "none"``).
    """
    import hashlib
    import socket

    if config.instance_id.lower() == "none":
        return None
    if config.instance_id:
        return config.instance_id
    host = host if host is not None else socket.gethostname()
    digest = hashlib.sha256(str(Path(state).absolute()).encode()).hexdigest()[:12]
    return f"mushrooms-{''.join(c for c in host if c.isalnum() or c in '.-')[:60] or 'host'}-{digest}"
