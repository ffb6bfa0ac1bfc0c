"""How long a ``group``-mode consumer waits for its partitions on librdkafka's mock cluster.

Usage::

    nice -n 5 .venv/bin/python benchmarks/speed/group_join.py [--out benchmarks/results]

The finding: through the loopback broker the daemon logged
``service_ready`` about 37 s before ``partitions_assigned``.  Each case here
starts a consumer with the daemon's own settings (:func:`consumer_config`)
in a process of its own and times ``subscribe`` -> ``on_assign``:

* a fresh group;
* right after the previous member closed cleanly (LeaveGroup), as after
  a ``systemctl restart``;
* right after the previous member was killed (``kill -9``);
* the same two with a static member id (``group.instance.id``), the
  remedy proposed for restarts;

for ``[kafka] session_timeout_s`` 30 (the default) and 6.  Wall-clock
numbers on a shared machine: the load average is printed beside them.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "daemon"))
from daemon_helpers import Broker  # noqa: E402

CHILD = r"""
import json, sys, time
import confluent_kafka
from mushrooms.daemon.kafka.consumer import consumer_config
from mushrooms.daemon.settings import KafkaConfig

bootstrap, topic, group, session_s, then, instance = sys.argv[1:7]
conf = consumer_config(KafkaConfig(topics=(topic,), group_id=group, bootstrap=bootstrap,
                                   session_timeout_s=float(session_s))) | {"log_level": 3}
if instance != "-":
    conf["group.instance.id"] = instance
c = confluent_kafka.Consumer(conf)
t0 = time.monotonic()
got = []
c.subscribe([topic], on_assign=lambda consumer, parts: got.append(time.monotonic() - t0))
while not got:
    c.consume(1, 0.1)
print(json.dumps({"assign_s": got[0]}), flush=True)
if then == "close":
    c.close()
else:  # stay a member until killed
    while True:
        c.consume(1, 0.1)
"""


def member(broker: Broker, topic: str, group: str, session_s: float, then: str, instance: str) -> tuple[Any, float]:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    p = subprocess.Popen([sys.executable, "-c", CHILD, broker.bootstrap, topic, group, str(session_s), then,
                          instance], stdout=subprocess.PIPE, text=True, env=env)
    return p, json.loads(p.stdout.readline())["assign_s"]


def cases(broker: Broker, session_s: float, static: bool) -> list[tuple[str, float]]:
    topic, group = f"join-{time.time_ns()}", f"mushrooms-{time.time_ns()}"
    broker.ensure_topic(topic)
    inst = f"mushrooms-{time.time_ns()}" if static else "-"
    out = []
    p, t = member(broker, topic, group, session_s, "close", inst)
    p.wait(60)
    out.append(("fresh group", t))
    p, t = member(broker, topic, group, session_s, "close", inst)
    p.wait(60)
    out.append(("after the previous member closed (LeaveGroup)", t))
    p, _ = member(broker, topic, group, session_s, "hold", inst)
    time.sleep(1.0)
    p.kill()
    p.wait(10)
    p, t = member(broker, topic, group, session_s, "close", inst)
    p.wait(60)
    out.append(("after the previous member was killed", t))
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "speed"))
    ap.add_argument("--sessions", default="30,6", help="session_timeout_s values, comma-separated")
    a = ap.parse_args()
    import confluent_kafka

    broker = Broker()
    lines = [f"# group_join.py {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, librdkafka "
             f"{confluent_kafka.libversion()[0]} mock cluster, {os.cpu_count()} cores, "
             f"load average at start {os.getloadavg()[0]:.1f}",
             "subscribe -> on_assign (s), daemon consumer settings", ""]
    for session_s in [float(x) for x in a.sessions.split(",")]:
        for static in (False, True):
            for name, t in cases(broker, session_s, static):
                line = (f"session_timeout_s={session_s:g} {'static member ' if static else ''}{name}: "
                        f"{t:.1f} s")
                print(line, flush=True)
                lines.append(line)
    lines.append(f"(load average after: {os.getloadavg()[0]:.1f})")
    out = Path(a.out) / "group_join.txt"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print(f"written {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
