"""Fixtures of the service tests: a real Kafka-protocol broker on loopback.

librdkafka's mock cluster lives inside the client that creates it, so the
fixture keeps that client (a Producer) alive for the whole session; the
daemon under test, a separate process, connects to it over TCP on 127.0.0.1.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterator

import confluent_kafka
import pytest

from mushrooms.tool.loopback_broker import MAX_MESSAGE_BYTES, LoopbackBroker

REPO = Path(__file__).resolve().parents[2]
SHARED_NOTICES = Path("/work/shared/data/notices")
DATA = Path(__file__).resolve().parent / "data"
BIG = MAX_MESSAGE_BYTES


def notice_path(name: str) -> Path:
    """A sample notice: our copy in tests/daemon/data, else the shared archive."""
    ours = REPO / "tests" / "data" / "notices"
    for base in (DATA, ours / "json", ours / "live", SHARED_NOTICES / "json", SHARED_NOTICES / "live"):
        p = base / name
        if p.is_file():
            return p
    pytest.skip(f"sample notice {name} not available")


def notice_bytes(name: str, superevent_id: str | None = None, time_created: str | None = None) -> bytes:
    """Notice bytes; with ``superevent_id`` / ``time_created`` only those fields are rewritten.

    ``time_created`` matters since decisions follow creation order: a
    notice relabelled from a 2023 event is newer than a 2018 retraction of the
    event it now names, so such a retraction must be dated after it.
    """
    raw = notice_path(name).read_bytes()
    if superevent_id is None and time_created is None:
        return raw
    doc = json.loads(raw)
    if superevent_id is not None:
        doc["superevent_id"] = superevent_id
    if time_created is not None:
        doc["time_created"] = time_created
    return json.dumps(doc).encode()


def live_copy(name: str, superevent_id: str, now: str, farther: float | None = None) -> bytes:
    """Notice ``name`` sent again live: ``time_created`` = ``event.time`` = ``now``.

    Its sky map is left as it is (so its header's ``DATE-OBS`` is stale) unless
    ``farther``: then DISTMU and DISTSIGMA are multiplied by it, DISTNORM divided
    by its square and DISTMEAN/DISTSTD scaled (the same event that far away).
    ``external_coinc`` is dropped, so the GW map is the one planned.
    """
    import base64
    import io

    from astropy.io import fits

    d = json.loads(notice_path(name).read_bytes())
    d["superevent_id"], d["time_created"], d["event"]["time"] = superevent_id, now, now
    d["external_coinc"] = None
    if farther:
        with fits.open(io.BytesIO(base64.b64decode(d["event"]["skymap"]))) as hdul:
            t = hdul[1]
            t.data  # load the table before editing it
            t.data["DISTMU"] *= farther
            t.data["DISTSIGMA"] *= farther
            t.data["DISTNORM"] /= farther ** 2
            for key in ("DISTMEAN", "DISTSTD"):
                if key in t.header:
                    t.header[key] = float(t.header[key]) * farther
            out = io.BytesIO()
            hdul.writeto(out)
        d["event"]["skymap"] = base64.b64encode(out.getvalue()).decode()
    return json.dumps(d).encode()


def final_numbers(messages: list[dict[str, Any]], superevent_id: str) -> dict[str, Any]:
    """What a job ended with: revision 1's and the optimiser's (coverage, expected detections), and who won.

    The optimiser's numbers come from revision 2 when it was published, else
    from the ``plan_final`` reason (``... would detect a kilonova with probability E % against ... %
    (expected detections) and cover C % against ...``).
    """
    import re

    mine = [m for m in messages if ((m.get("event") or {}).get("superevent_id") or m.get("superevent_id"))
            == superevent_id]
    plans = [m for m in mine if m.get("type") == "plan"]
    r1 = next(p for p in plans if p.get("revision") == 1)
    r2 = next((p for p in plans if p.get("revision") == 2), None)
    out: dict[str, Any] = {"r1": r1, "r2": r2, "c1": r1["metrics"]["coverage"],
                           "e1": r1["metrics"]["expected_detections"]}
    if r2 is not None:
        out.update(c2=r2["metrics"]["coverage"], e2=r2["metrics"]["expected_detections"], won=2,
                   solver2=r2["metrics"]["solver"], reason="")
    else:
        final = next(m for m in mine if m.get("type") == "plan_final")
        m = re.search(r"with probability ([0-9.]+) % against [0-9.]+ % \(expected detections\) and cover "
                      r"([0-9.]+) % against", final["reason"])
        out.update(e2=float(m.group(1)) / 100 if m else None, c2=float(m.group(2)) / 100 if m else None, won=1,
                   solver2="-", reason=final["reason"])
    return out


class Broker(LoopbackBroker):
    """The mock cluster and a producer bound to it: the library's loopback broker (what ``mushrooms rehearse``
    starts), with the tests' readers and offset checks."""

    def __init__(self) -> None:
        super().__init__(timeout_s=30.0)

    def committed(self, topic: str, group: str) -> dict[int, tuple[int, int]]:
        """partition -> (committed offset of ``group``, high watermark)."""
        c = confluent_kafka.Consumer({"bootstrap.servers": self.bootstrap, "group.id": group})
        try:
            parts = sorted(c.list_topics(topic, timeout=10).topics[topic].partitions)
            tps = c.committed([confluent_kafka.TopicPartition(topic, p) for p in parts], timeout=10)
            return {tp.partition: (tp.offset, c.get_watermark_offsets(tp, timeout=10)[1]) for tp in tps}
        finally:
            c.close()

    def fresh_topics(self) -> tuple[str, str, str]:
        """New (input topic, outbound topic, consumer group) names, both topics created."""
        tag = str(time.time_ns())
        topic, out_topic, group = f"gwalert-{tag}", f"plans-{tag}", f"mushrooms-{tag}"
        self.ensure_topic(topic)
        self.ensure_topic(out_topic)
        return topic, out_topic, group

    def reader(self, topic: str, group: str) -> "Reader":
        return Reader(self.bootstrap, topic, group)


class Reader:
    """A plain consumer of the outbound topic (manual assignment, from the start)."""

    def __init__(self, bootstrap: str, topic: str, group: str) -> None:
        self.c = confluent_kafka.Consumer({
            "bootstrap.servers": bootstrap, "group.id": group, "enable.auto.commit": False,
            "auto.offset.reset": "earliest", "fetch.max.bytes": BIG, "max.partition.fetch.bytes": BIG,
        })
        md = self.c.list_topics(topic, timeout=10)
        parts = sorted(md.topics[topic].partitions)
        self.c.assign([confluent_kafka.TopicPartition(topic, p, confluent_kafka.OFFSET_BEGINNING) for p in parts])
        self.messages: list[dict[str, Any]] = []

    def wait_for(self, predicate: Callable[[list[dict[str, Any]]], bool], timeout_s: float,
                 alive: Callable[[], None] | None = None) -> list[dict[str, Any]]:
        end = time.monotonic() + timeout_s
        while not predicate(self.messages):
            if time.monotonic() > end:
                raise AssertionError(f"timed out; got {summary(self.messages)}")
            if alive is not None:
                alive()
            for m in self.c.consume(10, 0.5):
                if m.error() is None:
                    self.messages.append(json.loads(m.value()))
        return self.messages

    def drain(self, quiet_s: float = 5.0) -> list[dict[str, Any]]:
        """Read until the topic has been quiet for ``quiet_s`` (s); every message read so far."""
        quiet = time.monotonic()
        while time.monotonic() - quiet < quiet_s:
            for m in self.c.consume(10, 0.5):
                if m.error() is None:
                    self.messages.append(json.loads(m.value()))
                    quiet = time.monotonic()
        return list(self.messages)

    def close(self) -> None:
        self.c.close()


def summary(messages: list[dict[str, Any]]) -> list[tuple[Any, ...]]:
    out = []
    for m in messages:
        ev = m.get("event") or {}
        out.append((m.get("type"), ev.get("superevent_id") or m.get("superevent_id"), m.get("plan_id"),
                    m.get("supersedes")))
    return out


@pytest.fixture(scope="session")
def broker() -> Iterator[Broker]:
    b = Broker()
    yield b
    b.producer.flush(5)


TEST_CONFIG = """
[scheduler]
solver = "greedy"
nside = 64
min_gain = 0.0
min_coverage = 0.0

[policy]
allow_mock = true
max_notice_age_s = 0
max_event_age_s = 0

[daemon]
heartbeat_s = 2
job_deadline_s = 600

"""

#: The mock broker's sections of a test config: input ``{topic}`` read by ``{group}`` (manual
#: assignment), plans to ``{out_topic}``; tests and benchmarks put their own sections before it.
BROKER_SECTIONS = """
[kafka]
topics = ["{topic}"]
group_id = "{group}"
assignment = "manual"
poll_timeout_s = 0.5

[outbound]
sink = "kafka"
topic = "{out_topic}"
retry_initial_s = 0.5
retry_max_s = 5
"""
TEST_CONFIG += BROKER_SECTIONS


def directory_outbox_config(tmp_path: Path) -> str:
    """A small in-process service config: greedy at nside 64, mock notices planned, the state file and a
    directory outbox in ``tmp_path`` (the text of ``config.toml``; a caller appends its own sections)."""
    return f"""
[scheduler]
solver = "greedy"
nside = 64
time_step_s = 600.0
min_gain = 0.0
min_coverage = 0.0

[policy]
allow_mock = true
max_notice_age_s = 0
max_event_age_s = 0

[daemon]
state_path = "{tmp_path / 'state.sqlite'}"

[outbound]
sink = "directory"
directory = "{tmp_path / 'outbox'}"
"""


def write_config(path: Path, topic: str, out_topic: str, group: str, extra: str = "") -> Path:
    path.write_text(TEST_CONFIG.format(topic=topic, out_topic=out_topic, group=group) + extra)
    return path


class Daemon:
    """``mushrooms run`` in a real subprocess; output goes to a log file."""

    def __init__(self, workdir: Path, args: list[str], env: dict[str, str] | None = None,
                 gate: Path | None = None, wrapper: Path | None = None) -> None:
        """``gate``: run through ``gated_run.py`` (jobs wait while ``gate/hold`` exists);
        ``wrapper``: run through that script (``script ARGS`` runs ``mushrooms run ARGS``)."""
        self.workdir = workdir
        self.gate = gate
        self.log = workdir / f"daemon-{time.time_ns()}.log"
        self.args = args
        e = dict(os.environ)
        e.pop("NOTIFY_SOCKET", None)
        e.pop("WATCHDOG_USEC", None)
        # the code under test, not whatever `mushrooms` the venv installed (a git worktree's own checkout)
        e["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), e.get("PYTHONPATH", "")) if p)
        e.update(env or {})
        if gate is not None:
            gate.mkdir(parents=True, exist_ok=True)
            e["MUSHROOMS_TEST_GATE"] = str(gate)
            cmd = [sys.executable, str(Path(__file__).with_name("gated_run.py")), *args]
        elif wrapper is not None:
            cmd = [sys.executable, str(wrapper), *args]
        else:
            cmd = [sys.executable, "-m", "mushrooms.cli", "run", *args]
        self._fh = open(self.log, "wb")
        self.proc = subprocess.Popen(
            cmd,
            cwd=workdir, stdout=self._fh, stderr=subprocess.STDOUT, env=e,
        )

    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def alive(self) -> None:
        if self.proc.poll() is not None:
            raise AssertionError(f"daemon exited with {self.proc.returncode}:\n{self.text()[-4000:]}")

    def wait_log(self, needle: str, timeout_s: float = 60.0, count: int = 1) -> str:
        end = time.monotonic() + timeout_s
        while True:
            text = self.text()
            if text.count(needle) >= count:
                return text
            self.alive()
            if time.monotonic() > end:
                raise AssertionError(f"{needle!r} not seen in the daemon log:\n{text[-4000:]}")
            time.sleep(0.1)

    def hold(self) -> None:
        """From now on planning jobs wait in front of their schedulers."""
        assert self.gate is not None
        (self.gate / "hold").touch()

    def release(self) -> None:
        """Let held jobs go on."""
        assert self.gate is not None
        (self.gate / "hold").unlink(missing_ok=True)

    def wait_held(self, superevent_id: str, timeout_s: float = 120.0) -> None:
        """Wait until a job of the superevent is held in front of a scheduler."""
        assert self.gate is not None
        end = time.monotonic() + timeout_s
        while not list(self.gate.glob(f"entered-{superevent_id}-*")):
            self.alive()
            if time.monotonic() > end:
                raise AssertionError(f"no job of {superevent_id} reached the gate:\n{self.text()[-4000:]}")
            time.sleep(0.05)

    def kill9(self) -> None:
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(10)
        self._fh.close()

    def stop(self, sig: int = signal.SIGTERM, timeout_s: float = 60.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
                raise AssertionError(f"daemon did not stop on {sig}:\n{self.text()[-4000:]}")
        self._fh.close()
        return self.proc.returncode


def notify_listener(path: Path) -> tuple[socket.socket, list[bytes]]:
    """A datagram socket at ``path`` standing in for systemd's notify socket, and what it was sent (filled by a
    thread until the socket is closed)."""
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(str(path))
    seen: list[bytes] = []

    def listen() -> None:
        while True:
            try:
                seen.append(notify.recv(4096))
            except OSError:
                return

    threading.Thread(target=listen, daemon=True).start()
    return notify, seen


@pytest.fixture
def daemons() -> Iterator[list[Daemon]]:
    started: list[Daemon] = []
    yield started
    for d in started:
        if d.proc.poll() is None:
            d.proc.kill()
            d.proc.wait(10)
