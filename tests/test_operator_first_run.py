"""A new operator's first commands on a fresh directory ("mend" item 5): what they say must lead somewhere.

Found by running, in an empty directory with no config, ``mushrooms demo``,
then ``mushrooms status``, ``preflight`` and ``rehearse`` as their ``--help``
suggests:

* ``status`` after ``demo`` said only ``.../mushrooms-state.sqlite: no such
  state file``: the demo's state is ``mushrooms-demo/state.sqlite``, and
  nothing said so, nor that ``--state`` picks a file;
* ``demo --help`` did not say where ``--out`` goes by default, and the demo
  did not say how to look at its result with ``status``;
* ``trigger <superevent id>`` with the default state path (not the demo's)
  created an empty state file, an outbox folder and a "rejected" notice
  there, which ``status`` then showed as an event: now one line, nothing made;
* ``rehearse``'s verdict on a submission named the queues' name base
  (``ToO_GW_<event>_<tag>``), which is no queue's name: Kowalski holds
  ``<base>_1`` ... ``<base>_K`` (the daemon's log line now carries them).
Real processes (the CLI as installed), a real notice through the real submitter.
"""

from __future__ import annotations

import logging
import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def mushrooms(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "MUSHROOMS_CONFIG"}
    env["PYTHONPATH"] = str(REPO)
    return subprocess.run([sys.executable, "-m", "mushrooms.cli", *args], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=600)


def test_status_on_a_fresh_directory_says_how_to_name_a_state_file(tmp_path) -> None:
    r = mushrooms("status", cwd=tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    (line,) = [x for x in r.stderr.splitlines() if x.startswith("mushrooms status:")]
    assert "no such state file" in line and "--state FILE" in line, line
    assert "mushrooms-demo/state.sqlite" in line, line  # where the demo put its state
    assert "[daemon] state_path" in line, line


def test_demo_says_where_it_writes_and_how_to_look_at_it_with_status(tmp_path) -> None:
    helped = mushrooms("demo", "--help", cwd=tmp_path)
    assert "default mushrooms-demo" in " ".join(helped.stdout.split()), helped.stdout
    r = mushrooms("demo", "--solver", "greedy", cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    hint = re.search(r"mushrooms status --state (\S+)", r.stdout)
    assert hint and hint.group(1) == "mushrooms-demo/state.sqlite", r.stdout[-800:]
    again = mushrooms("status", "--state", hint.group(1), cwd=tmp_path)
    assert again.returncode == 0 and "MS260605l" in again.stdout, again.stdout + again.stderr


def test_rehearse_names_the_queues_of_a_submission_not_their_name_base(tmp_path, caplog) -> None:
    """The submitter's own log line (Kowalski refused: nothing listens) as ``rehearse`` reads and judges it."""
    import socket

    from mushrooms.tool.rehearsal import Rehearsal, RehearsalFailed
    from mushrooms.tool.rehearse_watch import log_words, parse_log_line

    sys.path.insert(0, str(REPO / "tests" / "daemon"))
    from test_submissions import World, _config

    dead = socket.socket()
    dead.bind(("127.0.0.1", 0))  # bound, never listening: connection refused
    try:
        world = World(tmp_path / "state.sqlite", _config(f"http://127.0.0.1:{dead.getsockname()[1]}"))
        caplog.set_level(logging.INFO, logger="mushrooms.daemon.submit")
        world.notice("MS181101ab-preliminary.json")
        world.submitter.step()
    finally:
        dead.close()
    from mushrooms.daemon.submission.rows import submissions

    (sub,) = submissions(world.store)
    names = sub.queue_names()
    world.store.close()
    assert len(names) > 3
    few = f"queues {names[0]}, {names[1]}, {names[2]} +{len(names) - 3} more"
    lines = {r.getMessage().split()[0]: f"2026-12-06 17:00:00,000 {r.levelname} {r.name}: {r.getMessage()}"
             for r in caplog.records if r.getMessage().startswith("event=submission_")}
    pending = parse_log_line(lines["event=submission_pending"])
    assert log_words(pending) == f"submission of {sub.plan_id} ({few}) to kowalski waits to be sent", log_words(pending)
    watch = Rehearsal.__new__(Rehearsal)
    watch.events = [parse_log_line(lines["event=submission_retry"])]
    try:
        watch._judge_outcomes()
    except RehearsalFailed as failed:
        said = str(failed)
    else:
        raise AssertionError("a submission that did not reach the queue passed the rehearsal")
    assert f"submission of {sub.plan_id} ({few}) did not reach the queue" in said, said
    assert f"{sub.queue_name} " not in said  # the base alone is no queue


def test_trigger_of_a_superevent_without_a_state_file_creates_nothing_and_says_why(tmp_path) -> None:
    r = mushrooms("trigger", "MS260605l", cwd=tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    made = sorted(p.name for p in tmp_path.iterdir())
    lines = [x for x in r.stderr.splitlines() if x.startswith("mushrooms trigger:")]
    assert len(lines) == 1 and "no such state file" in lines[0] and "--state FILE" in lines[0], (r.stderr, made)
    assert made == [], made  # no state file, no outbox
