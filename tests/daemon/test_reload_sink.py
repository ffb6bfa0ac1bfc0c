"""A reload (SIGHUP) with a new ``[outbound]`` sink closes the old one: no thread nor socket left (issue 52 follow-up).

The daemon built the new sink and dropped the old one unclosed: a Kafka sink's
producer (librdkafka's threads, its sockets to the broker) and a directory
sink's page-drawing thread stayed for the life of the process, one more at
every reload.  Here the real daemon on the loopback broker is reloaded with a
new outbound topic again and again; its librdkafka threads (``rdk:*`` in
``/proc/PID/task/*/comm``) and its sockets (``/proc/PID/fd``) must come back
to what they were after the first reload, and a plan published after the
reloads shows the last sink works.  (Python's own threads are not counted
there: the timer's thread pool grows as its jobs overlap.)  What the reload
closes is the sink, not the webhook it tells: in process below, through the
service's wrappers, with a directory sink's page-drawing thread.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

from daemon_helpers import Daemon, notice_bytes, write_config


def _threads(pid: int) -> tuple[int, int]:
    """(librdkafka's threads, all threads) of process ``pid``."""
    names = []
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            names.append(Path(f"/proc/{pid}/task/{tid}/comm").read_text().strip())
        except OSError:  # a thread that ended meanwhile
            pass
    return sum(n.startswith("rdk:") for n in names), len(names)


def _sockets(pid: int) -> int:
    n = 0
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            n += os.readlink(f"/proc/{pid}/fd/{fd}").startswith("socket:")
        except OSError:
            pass
    return n


def _counts(pid: int) -> tuple[int, int, int]:
    rdk, threads = _threads(pid)
    return rdk, threads, _sockets(pid)


def _steady(d: Daemon, timeout_s: float = 60.0) -> tuple[int, int, int]:
    """The counts once they stay the same for 2 s (librdkafka connects and a closed producer ends on its own time)."""
    end = time.monotonic() + timeout_s  # a hang guard only
    last, since = None, time.monotonic()
    while time.monotonic() < end:
        d.alive()
        now = _counts(d.proc.pid)
        if now != last:
            last, since = now, time.monotonic()
        elif time.monotonic() - since >= 2.0:
            break
        time.sleep(0.2)
    return last


def _reload(d: Daemon, cfg: Path, old: str, new: str, n: int) -> None:
    cfg.write_text(cfg.read_text().replace(old, new))
    d.proc.send_signal(signal.SIGHUP)
    d.wait_log("event=config_reloaded", 60, count=n)


def test_a_reload_with_a_new_sink_closes_the_old_one(broker, daemons, tmp_path):
    topic, out, group = broker.fresh_topics()
    out2 = out + "-b"
    broker.ensure_topic(out2)
    cfg = write_config(tmp_path / "config.toml", topic, out, group)
    d = Daemon(tmp_path, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(tmp_path / "s.sqlite")])
    daemons.append(d)
    d.wait_log("event=service_ready", 180)
    _reload(d, cfg, f'topic = "{out}"', f'topic = "{out2}"', 1)
    base = _steady(d)
    for n in range(2, 6):  # four more sinks, each replacing the last
        a, b = (out2, out) if n % 2 == 0 else (out, out2)
        _reload(d, cfg, f'topic = "{a}"', f'topic = "{b}"', n)
    end = time.monotonic() + 60  # a hang guard: the old producers close on the timer thread
    while (now := _counts(d.proc.pid)) > base and time.monotonic() < end:
        d.alive()
        time.sleep(0.5)
    after = _steady(d)
    print(f"after the first reload: rdk threads, threads, sockets = {base}; after four more: {after}")
    assert after[0] <= base[0], f"librdkafka threads {base[0]} -> {after[0]}: the old sinks' producers are left"
    assert after[2] <= base[2], f"sockets {base[2]} -> {after[2]}: the old sinks' connections are left"
    assert d.text().count("event=sink_closed") == 5  # the first sink too, replaced by the first reload

    broker.produce(topic, notice_bytes("MS181101ab-preliminary.json", "MS181101ab"), key=b"MS181101ab")
    reader = broker.reader(out2, group + "-reader")  # the fifth reload's sink
    try:
        reader.wait_for(lambda ms: any(m.get("type") == "plan" for m in ms), 180, alive=d.alive)
    finally:
        reader.close()
    assert d.stop() == 0


def test_closing_a_replaced_sink_ends_its_threads_and_keeps_the_webhook(tmp_path):
    import threading
    from types import SimpleNamespace

    from mushrooms.daemon.ops.announce import NotifyingSink
    from mushrooms.daemon.ops.metrics import ObservedSink
    from mushrooms.daemon.ops.webhook import Webhook
    from mushrooms.daemon.reload import _close_replaced
    from mushrooms.daemon.sinks import DirectorySink
    from mushrooms.report.files import SummarisingSink

    hook = Webhook("http://127.0.0.1:9/hook/secret", "json", timeout_s=1.0)
    pages = SummarisingSink(DirectorySink(tmp_path / "outbox"))
    old = ObservedSink(NotifyingSink(pages, hook), metrics=None, received_wall=lambda plan_id: None)
    service = SimpleNamespace(pipeline=SimpleNamespace(store=SimpleNamespace(publish_lock=threading.Lock())),
                              config=SimpleNamespace(outbound=SimpleNamespace(delivery_timeout_s=1.0)))
    try:
        assert pages._thread.is_alive()
        _close_replaced(service, old)
        assert not pages._thread.is_alive(), "the replaced sink's thread is left"
        assert hook._thread.is_alive(), "the webhook the new sink tells was closed with the old sink"
    finally:
        hook.close(1.0)
