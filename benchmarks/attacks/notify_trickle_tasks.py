"""Issue 52, finding 3, end to end: 480 events against a webhook that trickles its answer, under TasksMax=256.

The unit sets ``TasksMax=256``.  This puts a process running the service's real
notification path (``open_webhook`` of ``[notify]`` with the URL from
``$MUSHROOMS_NOTIFY_URL``, wrapped in the ``NotifyingSink`` the daemon uses)
into a pids cgroup with ``pids.max = 256`` (cgroup v2 when its ``pids``
controller can be used, else the v1 ``pids`` hierarchy, which has the same
``pids.max``; with neither, only the process' own thread count is watched and
the output says so).  Then:

1. a webhook on loopback answers every POST one byte every 0.1 s (a status
   line and a header that never end: faster than any per-read timeout);
2. the process publishes 480 submission messages (one per event), one every
   0.25 s, and then waits for what is queued to be posted or given up;
3. the webhook recovers (answers 200 at once) and 20 more messages are published:
   how many reach it says whether notifications still flow.

Printed: a timeline (tasks in the cgroup, the sender's counts, connections
the webhook holds open), then the peaks, the cgroup's refused task creations
(``pids.events``), the log's event counts and whether the URL's secret is in
the log.  Run it on the code to test with ``PYTHONPATH`` (a checkout of
main, or this branch)::

    PYTHONPATH=$PWD python benchmarks/attacks/notify_trickle_tasks.py > out.txt
    PYTHONPATH=$PWD python benchmarks/attacks/notify_trickle_tasks.py --pace 0 > burst.txt  # all 480 at once

Needs root for the cgroup (else the in-process count only).  About 3 to 5 min.
"""

from __future__ import annotations

import json
import os
import selectors
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

EVENTS = 480
PACE_S = 0.25
TIMEOUT_S = 0.2  # [notify] timeout_s: the webhook's bytes come every 0.1 s, faster than it
DRIP_S = 0.1
PIDS_MAX = 256
AFTER = 20
SECRET = "s3cr3t-attack-token"
TRICKLE = b"HTTP/1.1 200 OK\r\nX-Slow: " + b"." * 1_000_000


class TricklingWebhook:
    """One thread, any number of connections: each request is read, then answered one byte every ``DRIP_S``,
    or at once with 200 once :attr:`healthy`."""

    def __init__(self) -> None:
        self.sel = selectors.DefaultSelector()
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.srv.setblocking(False)
        self.sel.register(self.srv, selectors.EVENT_READ)
        self.port = self.srv.getsockname()[1]
        self.conns: dict[socket.socket, dict] = {}
        self.healthy = False
        self.texts: list[str] = []
        self.accepted = 0
        self.peak_open = 0
        self.stop = False
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        next_drip = time.monotonic()
        while not self.stop:
            for key, _ in self.sel.select(timeout=0.02):
                if key.fileobj is self.srv:
                    try:
                        conn, _ = self.srv.accept()
                    except OSError:
                        continue
                    conn.setblocking(False)
                    self.conns[conn] = {"buf": b"", "answering": False, "at": 0}
                    self.sel.register(conn, selectors.EVENT_READ)
                    self.accepted += 1
                    self.peak_open = max(self.peak_open, len(self.conns))
                else:
                    self._read(key.fileobj)
            if time.monotonic() >= next_drip:
                next_drip = time.monotonic() + DRIP_S
                for conn, st in list(self.conns.items()):
                    if st["answering"]:
                        self._send(conn, TRICKLE[st["at"]:st["at"] + 1])
                        st["at"] += 1

    def _read(self, conn: socket.socket) -> None:
        st = self.conns.get(conn)
        if st is None:
            return
        try:
            chunk = conn.recv(65536)
        except OSError:
            chunk = b""
        if not chunk:
            self._close(conn)
            return
        st["buf"] += chunk
        head, sep, body = st["buf"].partition(b"\r\n\r\n")
        if not sep or st["answering"]:
            return
        length = next((int(v) for k, v in (h.split(b":", 1) for h in head.split(b"\r\n")[1:] if b":" in h)
                       if k.strip().lower() == b"content-length"), 0)
        if len(body) < length:
            return
        self.texts.append(json.loads(body[:length])["text"])
        st["answering"] = True
        if self.healthy:
            self._send(conn, b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\nConnection: close\r\n\r\nok")
            self._close(conn)

    def _send(self, conn: socket.socket, data: bytes) -> None:
        try:
            conn.send(data)
        except OSError:
            self._close(conn)

    def _close(self, conn: socket.socket) -> None:
        if self.conns.pop(conn, None) is not None:
            self.sel.unregister(conn)
            conn.close()


def pids_cgroup() -> tuple[Path | None, str]:
    """A new pids cgroup with pids.max = PIDS_MAX, and which hierarchy it is in (or None and why not)."""
    name = f"mushrooms-notify-attack-{os.getpid()}"
    v2 = Path("/sys/fs/cgroup")
    for root, kind in ((v2, "cgroup v2"), (Path("/sys/fs/cgroup/unified"), "cgroup v2 (unified)"),
                       (Path("/sys/fs/cgroup/pids"), "cgroup v1 pids")):
        try:
            if kind.startswith("cgroup v2") and "pids" not in (root / "cgroup.controllers").read_text().split():
                continue
            if kind.startswith("cgroup v2"):
                (root / "cgroup.subtree_control").write_text("+pids")
            group = root / name
            group.mkdir()
            (group / "pids.max").write_text(str(PIDS_MAX))
            return group, kind
        except OSError:
            continue
    return None, "no writable pids cgroup here: only the process' own thread count is watched"


CHILD = r"""
import json, logging, os, sys, threading, time
logging.basicConfig(filename=sys.argv[2], level=logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
from mushrooms.daemon.ops.announce import NotifyingSink, open_webhook
from mushrooms.daemon.ops.webhook_settings import NotifyConfig
from mushrooms.daemon.sinks import MemorySink
events, pace, timeout, after = int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5]), int(sys.argv[6])
sys.stdin.readline()  # the parent has moved this process into the cgroup
hook = open_webhook(NotifyConfig(target="json", timeout_s=timeout, max_pending=100),
                    environ={"MUSHROOMS_NOTIFY_URL": sys.argv[1]})
sink = NotifyingSink(MemorySink(), hook)
def tasks():
    return int(open("/proc/self/status").read().split("Threads:")[1].split()[0])
def say(phase, **kw):
    print(json.dumps({"phase": phase, "tasks": tasks(), "threads": threading.active_count(), "sent": hook.sent,
                      "failed": hook.failed, "dropped": hook.dropped, "sender_alive": hook._thread.is_alive(), **kw}),
          flush=True)
def publish(k, tag):
    sid = f"S26{k:04d}{tag}"
    sink.publish({"type": "submission", "submission_id": sid, "superevent_id": sid, "state": "failed",
                  "queue_name": f"ToO_GW_{sid}_r1", "target": "kowalski", "reason": "HTTP 503"})
for k in range(events):
    try:
        publish(k, "a")
    except Exception as exc:
        say("publish_error", error=f"{type(exc).__name__}: {exc}")
    if k % 40 == 39:
        say("events", posted=k + 1)
    time.sleep(pace)
end = time.monotonic() + 120
while time.monotonic() < end and hook._thread.is_alive() and (hook.sent + hook.failed + hook.dropped) < events:
    time.sleep(0.5)
say("drained")
sys.stdin.readline()  # the parent made the webhook healthy
for k in range(after):
    publish(k, "b")
    time.sleep(0.05)
end = time.monotonic() + 30
while time.monotonic() < end and hook._thread.is_alive() and (hook.sent + hook.failed + hook.dropped) < events + after:
    time.sleep(0.2)
say("after_recovery")
"""


def report(hook: TricklingWebhook, group: Path | None, peak: int, before: int | None, last: dict, text: str) -> None:
    """The peaks, the refused task creations, the messages after recovery, the log's counts."""
    after = [t for t in hook.texts[before:] if "b: queue" in t] if before is not None else []
    events = Path(f"{group}/pids.events").read_text().split() if group is not None else []
    print()
    print(f"peak tasks in the cgroup: {peak if group else '-'} (pids.max {PIDS_MAX if group else '-'}); "
          f"task creations refused (pids.events): {events[1] if len(events) > 1 else '-'}")
    print(f"webhook: {hook.accepted} connections accepted, at most {hook.peak_open} open at once")
    print(f"after recovery: {len(after)} of {AFTER} new messages reached the webhook; sender alive at the end: "
          f"{last.get('sender_alive')}")
    counts = {e: text.count(f"event={e}") for e in ("notify_sent", "notify_failed", "notify_dropped")}
    print(f"log: {counts}, 'Exception in thread': {text.count('Exception in thread')}, "
          f"\"can't start new thread\": {text.count(chr(39).join(['can', 't start new thread']))}, "
          f"secret in the log: {SECRET in text}")
    tail = [line for line in text.splitlines() if line.strip() and " INFO " not in line and " WARNING " not in line][-6:]
    if tail:
        print("child's stderr, last lines:\n  " + "\n  ".join(tail))


def main() -> int:
    global PACE_S
    import mushrooms

    if sys.argv[1:2] == ["--pace"]:
        PACE_S = float(sys.argv[2])

    print(f"code under test: {Path(mushrooms.__file__).parent}; python {sys.version.split()[0]}")
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    hook = TricklingWebhook()
    group, kind = pids_cgroup()
    print(f"pids cgroup: {group or '-'} ({kind}), pids.max = {PIDS_MAX if group else '-'}")
    print(f"{EVENTS} events, one every {PACE_S} s; [notify] timeout_s = {TIMEOUT_S}; the webhook sends one byte "
          f"every {DRIP_S} s")
    log = Path(f"/tmp/notify-trickle-{os.getpid()}.log")
    url = f"http://127.0.0.1:{hook.port}/services/T000/B000/{SECRET}"
    child = subprocess.Popen([sys.executable, "-c", CHILD, url, str(log), str(EVENTS), str(PACE_S), str(TIMEOUT_S),
                              str(AFTER)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
    if group is not None:
        (group / "cgroup.procs").write_text(str(child.pid))
    child.stdin.write("go\n")
    child.stdin.flush()
    peak = {"pids": 0}
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            if group is not None:
                try:
                    peak["pids"] = max(peak["pids"], int((group / "pids.current").read_text()))
                except (OSError, ValueError):
                    pass
            time.sleep(0.1)

    threading.Thread(target=sample, daemon=True).start()
    t0 = time.monotonic()
    stderr: list[str] = []
    threading.Thread(target=lambda: stderr.extend(child.stderr), daemon=True).start()
    last: dict = {}
    before = None
    for line in child.stdout:
        last = json.loads(line)
        pids = (group / "pids.current").read_text().strip() if group is not None else "-"
        print(f"[{time.monotonic() - t0:6.1f} s] {last['phase']:<15} posted={last.get('posted', '-'):<4} "
              f"cgroup_tasks={pids:<4} tasks={last['tasks']:<4} threads={last['threads']:<4} sent={last['sent']:<4} "
              f"failed={last['failed']:<4} dropped={last['dropped']:<4} sender_alive={last['sender_alive']} "
              f"webhook_open_connections={len(hook.conns)}" + (f" error={last['error']}" if 'error' in last else ""),
              flush=True)
        if last["phase"] == "drained":
            before = len(hook.texts)
            hook.healthy = True
            child.stdin.write("go\n")
            child.stdin.flush()
    child.wait(60)
    stop.set()
    report(hook, group, peak["pids"], before, last, log.read_text() + "".join(stderr))
    print(f"child exit status: {child.returncode}; wall {time.monotonic() - t0:.0f} s; "
          f"load {os.getloadavg()[0]:.2f}")
    hook.stop = True
    if group is not None:
        try:
            group.rmdir()
        except OSError as exc:
            print(f"(cgroup {group} not removed: {exc})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
