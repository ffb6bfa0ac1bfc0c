"""Outbound sinks: where plans and withdrawals are published.

A sink has one method, ``publish(message: dict) -> None``, which returns only
once the message is durably handed over and raises on failure (the message
then stays in the store's outbox and is retried).  Publishing the same
message twice must be harmless: the directory sink overwrites the same file,
the Kafka sink (:mod:`~mushrooms.daemon.kafka.sink`) keys messages by :func:`message_key`.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from pathlib import Path
from typing import Any, Mapping, Protocol, runtime_checkable

from ..scheduler_core.plan import strict_json

__all__ = ["Sink", "DirectorySink", "MemorySink", "message_key", "SinkError"]


class SinkError(RuntimeError):
    """A message could not be published."""


@runtime_checkable
class Sink(Protocol):
    """Where outbound messages go."""

    def publish(self, message: dict[str, Any]) -> None:
        """Publish one message (plan document or withdrawal); raise on failure."""
        ...


_SAFE = re.compile(r"[^A-Za-z0-9._-]")


def message_key(message: Mapping[str, Any]) -> str:
    """Stable key of an outbound message: ``plan_id`` (plans, not_observable answers), ``<plan_id>-final``,
    ``withdrawal_id`` or ``submission_id``.

    A ``plan_final`` message (the optimisation found nothing better: the
    named plan is final) is keyed by its plan's id with ``-final``.

    Raises
    ------
    SinkError
        When the message has neither.
    """
    kind = message.get("type")
    if kind == "plan_final":
        plan_id = message.get("plan_id")
        key = f"{plan_id}-final" if isinstance(plan_id, str) and plan_id else None
    elif kind == "submission":  # a plan's submission to ZTF's queue (daemon/submission/submitter.py)
        key = message.get("submission_id")
    else:
        key = message.get("plan_id") if kind in ("plan", "not_observable") else message.get("withdrawal_id")
    if not isinstance(key, str) or not key:
        raise SinkError(f"outbound message of type {kind!r} has no plan_id/withdrawal_id")
    return key


class DirectorySink:
    """Write each message as ``<key>.json`` in a directory, atomically.

    The file is written to a temporary name in the same directory, flushed
    and fsynced, then renamed over the final name (``os.replace``), and the
    directory is fsynced: a reader never sees a partial file, and a
    re-published message overwrites its own file.

    Parameters
    ----------
    directory : str or Path
        Created if missing.
    """

    def __init__(self, directory: str | Path):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)

    def path_for(self, message: Mapping[str, Any]) -> Path:
        """File a message is written to."""
        return self.directory / (_SAFE.sub("_", message_key(message)) + ".json")

    def publish(self, message: dict[str, Any]) -> None:
        target = self.path_for(message)
        data = (strict_json.dumps(message, indent=1) + "\n").encode()
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=self.directory)
        try:
            os.fchmod(fd, 0o644)  # mkstemp makes 0600; readers of the outbox need to read it
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, target)
        except BaseException:
            try:
                os.unlink(tmp)
            except OSError:
                pass
            raise
        try:
            dfd = os.open(self.directory, os.O_RDONLY)
        except OSError:
            return
        try:
            os.fsync(dfd)
        except OSError:
            pass
        finally:
            os.close(dfd)

    def close(self) -> None:
        """Nothing to release (symmetry with the Kafka sink)."""

    def __repr__(self) -> str:
        return f"DirectorySink({str(self.directory)!r})"


class MemorySink:
    """Keep messages in a list (tests); ``fail`` makes the next publishes raise."""

    def __init__(self) -> None:
        self.messages: list[dict[str, Any]] = []
        self.fail = 0

    def publish(self, message: dict[str, Any]) -> None:
        if self.fail:
            self.fail -= 1
            raise SinkError("sink unavailable (test)")
        self.messages.append(json.loads(strict_json.dumps(message)))

    def close(self) -> None:
        pass
