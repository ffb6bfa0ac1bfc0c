"""First-plan latency while the submission target hangs.

Usage::

    nice -n 5 .venv/bin/python benchmarks/speed/submit_latency.py [--events 4] [--out benchmarks/results]

Runs the real ``mushrooms run`` twice with the default ``[scheduler]``
(nside 256, hybrid) on the loopback mock Kafka broker:

* ``off``: ``[submit] target = "none"``;
* ``hanging``: ``[submit] target = "kowalski"`` against the Kowalski contract
  server of ``tests/daemon/contract_servers.py`` whose every PUT is held
  unanswered (``timeout_s = 10``: each attempt blocks the submitter thread 10 s).

Each run gets the same notices one after the other (the sample notices with
fresh superevent ids; the next is sent once the previous first plan is
logged) and reports each event's first-plan latency, the daemon's
``event=job_first_plan ... latency_s`` (notice consumed -> revision 1 stored).
The machine is shared: the load average is printed beside the numbers.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "daemon"))
sys.path.insert(0, str(REPO / "benchmarks" / "common"))  # benchmarks/common: the shared helpers

from contract_servers import KowalskiContract, loopback_server  # noqa: E402
from daemon_helpers import Broker, Daemon, notice_bytes  # noqa: E402
from latency_summary import latency_line, write_summary  # noqa: E402

NOTICES = ["MS181101ab-preliminary.json", "MS230425l-preliminary.json", "MS260605l-preliminary.json"]
TOKEN = "bench-token"

CONFIG = """
[policy]
allow_mock = true
max_notice_age_s = 0
max_event_age_s = 0

[kafka]
topics = ["{topic}"]
group_id = "{group}"
assignment = "manual"
poll_timeout_s = 0.5

[outbound]
sink = "directory"
directory = "{outbox}"
{submit}
"""


def run(broker: Broker, work: Path, label: str, submit: str, events: int) -> list[float]:
    topic = f"gwalert-{label}-{time.time_ns()}"
    broker.ensure_topic(topic)
    cfg = work / f"{label}.toml"
    cfg.write_text(CONFIG.format(topic=topic, group=f"bench-{label}-{time.time_ns()}", outbox=work / f"out-{label}",
                                 submit=submit))
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(work / f"{label}.sqlite")],
               env={"MUSHROOMS_SUBMIT_TOKEN": TOKEN})
    try:
        d.wait_log("event=service_ready", 300)
        latencies = []
        for i in range(events):
            sid = f"MS99{label[:2].upper()}{i:02d}"
            broker.produce(topic, notice_bytes(NOTICES[i % len(NOTICES)], sid), key=sid.encode())
            text = d.wait_log(f"event=job_first_plan superevent_id={sid} ", 300)
            m = re.search(rf"event=job_first_plan superevent_id={sid} .*?latency_s=([0-9.]+)", text)
            latencies.append(float(m.group(1)))
        if "target" in submit:
            print(f"  [{label}] submission lines in the log: {d.text().count('event=submission_retry')} retries, "
                  f"{d.text().count('event=submission_submitted')} submitted")
        return latencies
    finally:
        d.stop()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--events", type=int, default=4)
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "speed")
    args = ap.parse_args()
    broker = Broker()
    server = loopback_server()
    kowalski = KowalskiContract(server, TOKEN)
    kowalski.faults["PUT"] = ["hang"] * 10_000
    kowalski.hang_s = 900.0
    lines = [f"load before: {os.getloadavg()}"]
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        results = {}
        for label, submit in [
            ("off", ""),
            ("hanging", f'[submit]\ntarget = "kowalski"\nurl = "{kowalski.url}"\ntimeout_s = 10.0\n'),
        ]:
            results[label] = run(broker, work, label, submit, args.events)
            lines.append(latency_line(label, results[label], 2, f"load {os.getloadavg()}"))
    held = kowalski.hanging
    kowalski.release.set()
    lines.append(f"PUT requests the server held unanswered at the end: {held}")
    server.stop()
    write_summary(lines, args.out, "submit_latency.txt")
    return 0


if __name__ == "__main__":
    sys.exit(main())
