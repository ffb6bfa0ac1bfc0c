"""librdkafka's voice in the service's log, and whether the broker answers.

librdkafka writes its own lines to stderr, and when a broker is unreachable
or refuses the credentials it repeats them many times a second.  Here its
log is routed into Python logging (logger ``mushrooms.kafka``, through the
client's ``logger`` setting) behind a filter that lets one line of a kind
through per window and then says how often it repeated; and the client's
error and statistics callbacks keep a :class:`BrokerHealth` that the
heartbeat and the systemd status line report.
"""

from __future__ import annotations

import json
import logging
import re
import threading
import time
from typing import Any, Callable

__all__ = ["RepeatFilter", "BrokerHealth", "kafka_logger", "client_settings"]

log = logging.getLogger("mushrooms.kafka")

_VOLATILE = re.compile(r"\d+(\.\d+)?")  # counters and durations that change between repeats


class RepeatFilter(logging.Filter):
    """Let one record of a kind through per ``window_s``; count the rest.

    Records are of one kind when their text is the same with the numbers
    taken out (``after 0ms`` and ``after 3ms`` are one kind).  The first
    record after a window in which repeats were suppressed carries
    ``(N similar lines suppressed in the last W s)``.

    Parameters
    ----------
    window_s : float
        Length (s) of the window.
    clock : callable, optional
        Monotonic clock (tests).
    """

    def __init__(self, window_s: float = 60.0, clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__()
        self.window_s = float(window_s)
        self._clock = clock
        self._seen: dict[tuple[int, str], tuple[float, int]] = {}  # kind -> (window start, suppressed)
        self._lock = threading.Lock()
        self.suppressed = 0

    def filter(self, record: logging.LogRecord) -> bool:
        kind = (record.levelno, _VOLATILE.sub("#", record.getMessage()))
        now = self._clock()
        with self._lock:
            start, hidden = self._seen.get(kind, (None, 0))
            if start is not None and now - start < self.window_s:
                self._seen[kind] = (start, hidden + 1)
                self.suppressed += 1
                return False
            self._seen[kind] = (now, 0)
            if len(self._seen) > 1000:  # many kinds: forget the oldest windows
                for k in sorted(self._seen, key=lambda k: self._seen[k][0])[:500]:
                    del self._seen[k]
        if hidden:
            record.msg = f"{record.msg} ({hidden} similar line(s) suppressed in the last {self.window_s:.0f} s)"
        return True


_FILTER = RepeatFilter()


def kafka_logger() -> logging.Logger:
    """The logger librdkafka writes to (``mushrooms.kafka.librdkafka``), with repeats rate-limited."""
    lg = logging.getLogger("mushrooms.kafka.librdkafka")
    if _FILTER not in lg.filters:
        lg.addFilter(_FILTER)
    return lg


class BrokerHealth:
    """Whether the Kafka cluster answers, from the client's own callbacks.

    ``up`` is None until librdkafka's first statistics (a few seconds after
    start), then True while at least one broker connection is ``UP``.  A
    change is logged once (``event=broker_unreachable`` /
    ``event=broker_reachable``), never per reconnect attempt.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.up: bool | None = None
        self.since = time.time()
        self.last_error: str | None = None
        #: topic -> messages not yet consumed (consumer statistics; partitions with a known lag)
        self.lag: dict[str, int] = {}
        self._lock = threading.Lock()

    def _set(self, up: bool, detail: str | None = None) -> None:
        with self._lock:
            changed = self.up is not up
            if changed:
                self.up, self.since = up, time.time()
        if changed and up:
            log.info("event=broker_reachable client=%s", self.name)
        elif changed:
            log.warning("event=broker_unreachable client=%s error=%r", self.name, detail or self.last_error or "-")

    def on_error(self, err: Any) -> None:
        """librdkafka ``error_cb``: remember the error; all brokers down or refused credentials mean down."""
        from confluent_kafka import KafkaError

        self.last_error = str(err)
        code = err.code() if hasattr(err, "code") else None
        if code in (KafkaError._ALL_BROKERS_DOWN, KafkaError._AUTHENTICATION, KafkaError.SASL_AUTHENTICATION_FAILED):
            self._set(False, str(err))

    def on_message(self) -> None:
        """A message arrived: the broker answers."""
        if self.up is not True:
            self._set(True)

    def on_stats(self, text: str) -> None:
        """librdkafka ``stats_cb``: up when any broker connection is in state ``UP``."""
        try:
            stats = json.loads(text)
        except ValueError:
            return
        lag: dict[str, int] = {}
        for topic, t in (stats.get("topics") or {}).items():
            for pid, part in (t.get("partitions") or {}).items():
                n = part.get("consumer_lag", -1)
                if pid != "-1" and isinstance(n, int) and n >= 0:
                    lag[topic] = lag.get(topic, 0) + n
        self.lag = lag
        self._set(any(b.get("state") == "UP" for b in (stats.get("brokers") or {}).values()))

    def describe(self) -> str:
        """``up``, ``down`` or ``unknown`` (before the first statistics)."""
        return "unknown" if self.up is None else ("up" if self.up else "down")

    def status_text(self) -> str:
        """One phrase for the systemd status line."""
        if self.up is None:
            return "broker: connecting"
        if self.up:
            return "broker: up"
        since = time.strftime("%H:%M:%S", time.gmtime(self.since))
        return f"broker UNREACHABLE since {since} UTC ({(self.last_error or '')[:80]})"


def client_settings(health: BrokerHealth | None, stats_interval_s: float = 10.0) -> dict[str, Any]:
    """librdkafka settings that route its log and health here."""
    conf: dict[str, Any] = {"logger": kafka_logger()}
    if health is not None:
        conf.update({"error_cb": health.on_error, "stats_cb": health.on_stats,
                     "statistics.interval.ms": int(stats_interval_s * 1000)})
    return conf
