"""A restarted daemon's time to its partitions after a SIGKILL, ``[kafka] assignment = "group"`` or ``"manual"``.

The real ``mushrooms run`` (``--tree``'s package) on librdkafka's mock cluster,
one 4-partition topic, ``session_timeout_s`` 30 (the default): start, wait for
``event=consuming``, SIGKILL, start again at once; the restart's time is the
``since_start_s`` of its ``event=consuming`` line (process start -> partitions
assigned).  With the issue-25 tree the consumer is a static member
(``group.instance.id`` derived from host + state path, logged as
``group_instance_id=`` in ``event=consumer_started``); the pre-fix tree is not.

    PYTHONPATH=$PWD nice -n 5 python benchmarks/speed/restart_join.py --tree $PWD --label after [--rounds 2]
        [--assignment manual]

``--assignment manual`` is the single-instance remedy that needs no broker
support: every partition is assigned by the daemon itself from the group's
committed offsets, so no group coordinator holds a dead member's session.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests" / "daemon")]

from daemon_helpers import Broker, Daemon, write_config  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", default=str(ROOT))
    ap.add_argument("--label", default="after")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", default=None)
    ap.add_argument("--assignment", choices=("group", "manual"), default="group")
    a = ap.parse_args()
    out_path = Path(a.out or ROOT / "benchmarks" / "results" / "speed" / "restart_join" / f"restart_join_{a.label}.txt")
    work = Path(tempfile.mkdtemp(prefix="mushrooms-restart-"))
    load0 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    broker = Broker()
    topic, out_topic, group = broker.fresh_topics()
    cfg = write_config(work / "config.toml", topic, out_topic, group)
    cfg.write_text(cfg.read_text().replace('assignment = "manual"', f'assignment = "{a.assignment}"\nsession_timeout_s = 30'))
    args = ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(work / "state.sqlite")]
    env = {"PYTHONPATH": a.tree}
    needle = f"event=partitions_assigned mode={a.assignment}"  # logged by both trees

    def start() -> tuple[Daemon, float]:
        t0 = time.monotonic()
        d = Daemon(work, args, env=env)
        while needle not in d.text():
            d.alive()
            if time.monotonic() - t0 > 300:
                raise SystemExit(f"no assignment in 300 s:\n{d.text()[-3000:]}")
            time.sleep(0.05)
        line = next(ln for ln in d.text().splitlines() if needle in ln)
        where = re.search(r"(partitions|positions)=.*", line)
        return d, time.monotonic() - t0, where.group(0) if where else line
    lines = [f"# benchmarks/speed/restart_join.py {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, label {a.label}",
             f"# command: PYTHONPATH=$PWD nice -n 5 python benchmarks/speed/restart_join.py --tree {a.tree} "
             f"--label {a.label} --rounds {a.rounds} --assignment {a.assignment}",
             f"# uptime before: {load0}",
             f"# {a.assignment} mode, session_timeout_s 30, 4 partitions, librdkafka mock cluster",
             ""]
    d, t_first, parts = start()
    inst = re.search(r"group_instance_id=(\S+)", d.text())
    lines.append(f"first start: partitions assigned {t_first:.1f} s after the process was spawned ({parts}); "
                 f"group_instance_id={inst.group(1) if inst else '(not logged: no static membership)'}")
    for r in range(a.rounds):
        time.sleep(3)
        d.kill9()
        d, t, parts = start()
        lines.append(f"restart {r + 1} right after SIGKILL: partitions assigned {t:.1f} s after the process was "
                     f"spawned ({parts})")
    d.stop()
    lines.append(f"# uptime after: {subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}")
    out = "\n".join(lines) + "\n"
    print(out)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
