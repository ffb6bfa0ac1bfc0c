"""Attacks on the service's state and surroundings, fast cases: an event
that is never planned, a damaged or shared state file, planted trigger
files, raw-byte retention, the store closed under a retry, the unit's
limits.  Real SQLite, real pipeline (greedy, nside 64), real files."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import time
from pathlib import Path

import pytest

from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.sinks import MemorySink
from mushrooms.daemon.state.store import Store, StoreError
from mushrooms.daemon.intake.trigger import classify, pending_triggers, read_trigger, write_trigger
from mushrooms.scheduler_core.errors import InputError
from mushrooms.tool.config import load_config
from mushrooms.tool.overrides import override_config

from attack_helpers import FAST, REPO, notice_with, received_at


def _service_config(path: str | None, outbox: str, state: str):
    """What ``mushrooms run --bootstrap 127.0.0.1:9 --outbox OUTBOX --state STATE --allow-mock`` builds the service from."""
    return override_config(load_config(path), bootstrap="127.0.0.1:9", outbox=outbox, state=state, allow_mock=True)


def _pipeline(path: Path, sink=None) -> NoticePipeline:
    return NoticePipeline.from_config(FAST, Store(path), sink or MemorySink())


def _died(store: Store, job_id: int, times: int) -> None:
    """Start a job ``times`` times without finishing it, as a process killed mid-plan does."""
    for _ in range(times):
        assert store.start_job(job_id) is not None


# ---------------------------------------------------------------- 2. degrade, never drop
def test_a_clean_stop_does_not_count_as_a_died_start(tmp_path: Path) -> None:
    p = _pipeline(tmp_path / "s.sqlite")
    acc = p.accept(notice_with("MS181101ab"), "attack:1", received_at())
    for _ in range(5):  # five SIGTERM stops while the job ran
        p.store.start_job(acc.job.job_id)
        p.store.release_unfinished()
    job = p.store.job(acc.job.job_id)
    assert job.status == "pending" and job.attempts == 0
    out = p.run_job(job)
    assert out.decision == "plan" and out.published


def test_a_job_that_died_three_times_still_publishes_the_fast_plan(tmp_path: Path) -> None:
    config = FAST
    hybrid = NoticePipeline.from_config(config.__class__(**{**config.__dict__,
                                                "scheduler": config.scheduler.__class__(
                                                    **{**config.scheduler.__dict__, "solver": "hybrid"})}),
                            Store(tmp_path / "s.sqlite"), MemorySink())
    acc = hybrid.accept(notice_with("MS181101ab"), "attack:1", received_at())
    _died(hybrid.store, acc.job.job_id, 3)
    out = hybrid.run_job(hybrid.store.job(acc.job.job_id))
    assert out.decision == "plan" and out.published, out
    (msg,) = hybrid.sink.messages
    assert msg["metrics"]["solver"] == "greedy"


def test_an_event_whose_job_gave_up_is_planned_by_the_next_notice(tmp_path: Path) -> None:
    p = _pipeline(tmp_path / "s.sqlite")
    acc = p.accept(notice_with("MS181101ab"), "kafka:t:0:1", received_at())
    starts = 0
    while p.store.start_job(acc.job.job_id) is not None:  # every start died, the fast scheduler's too
        starts += 1
    assert starts == 5  # three with the optimiser, two with the fast scheduler
    assert p.store.job_status(acc.job.job_id) == "failed"
    again = p.accept(notice_with("MS181101ab"), "kafka:t:0:2", received_at())  # same map
    assert again.action == "plan", again
    out = p.run_job(again.job)
    assert out.published
    # and once a plan is out, the same map again is a duplicate
    assert p.accept(notice_with("MS181101ab"), "kafka:t:0:3", received_at()).action == "duplicate"


def test_a_redelivery_while_the_job_is_pending_is_a_duplicate(tmp_path: Path) -> None:
    p = _pipeline(tmp_path / "s.sqlite")
    first = p.accept(notice_with("MS181101ab"), "kafka:t:0:1", received_at())
    again = p.accept(notice_with("MS181101ab"), "kafka:t:0:1", received_at())
    assert again.action == "duplicate" and p.store.job_status(first.job.job_id) == "pending"


# ---------------------------------------------------------------- 6. damaged state file
def test_an_existing_empty_state_file_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "state.sqlite"
    path.write_bytes(b"")
    with pytest.raises(StoreError, match="empty"):
        Store(path)
    assert path.stat().st_size == 0  # left as found for the operator


def test_garbage_in_the_middle_of_the_state_file_is_detected(tmp_path: Path) -> None:
    path = tmp_path / "state.sqlite"
    p = _pipeline(path)
    for i in range(60):
        p.accept(notice_with(f"MS181101{chr(97 + i // 26)}{chr(97 + i % 26)}"), f"attack:{i}", received_at())
    p.store.close()
    size = path.stat().st_size
    assert size > 64 * 1024
    with open(path, "r+b") as fh:
        fh.seek(size // 2 // 4096 * 4096)
        fh.write(os.urandom(8192))
    with pytest.raises(StoreError, match="quick_check|damaged|malformed"):
        Store(path)


def test_the_service_exits_with_a_status_restart_does_not_loop_on(tmp_path: Path) -> None:
    from mushrooms.daemon.service import EXIT_STATE, Service

    state = tmp_path / "state.sqlite"
    state.write_bytes(b"")
    config = _service_config(None, outbox=str(tmp_path / "out"), state=str(state))
    assert Service(config, resolve_paths(config.daemon)).run() == EXIT_STATE
    unit = (REPO / "systemd" / "mushrooms.service").read_text()
    prevent = next(line for line in unit.splitlines() if line.startswith("RestartPreventExitStatus="))
    assert str(EXIT_STATE) in prevent.split("=", 1)[1].split()


# ---------------------------------------------------------------- 5. one state file, one daemon
def test_a_second_service_on_the_same_state_file_is_refused_whatever_its_pid_file(tmp_path: Path) -> None:
    from mushrooms.daemon.state.store import StateInUse, lock_state

    state = tmp_path / "state.sqlite"
    Store(state).close()
    held = lock_state(state)
    try:
        with pytest.raises(StateInUse, match=str(os.getpid())):
            lock_state(state)
        cfg = tmp_path / "other.toml"
        cfg.write_text('[daemon]\npid_file = "another.pid"\n')
        from mushrooms.daemon.service import Service

        config = _service_config(str(cfg), outbox=str(tmp_path / "out"), state=str(state))
        assert Service(config, resolve_paths(config.daemon)).run() == 1
    finally:
        held.release()
    lock_state(state).release()  # free again once released


# ---------------------------------------------------------------- 7. trigger files and permissions
def test_a_symlink_planted_in_the_trigger_directory_is_not_read(tmp_path: Path) -> None:
    secret = tmp_path / "protected.txt"
    secret.write_text("root:x:0:0\n")
    tdir = tmp_path / "triggers"
    tdir.mkdir()
    link = tdir / "00000000000000000001-1-notice.json"
    link.symlink_to(secret)
    fifo = tdir / "00000000000000000002-1-notice.json"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="symbolic link"):
        read_trigger(link)
    with pytest.raises(InputError, match="not a regular file"):
        read_trigger(fifo)  # and it does not block on the FIFO
    assert pending_triggers(tdir) == []
    assert sorted(p.name for p in tdir.iterdir()) == sorted([f".{fifo.name}.refused", f".{link.name}.refused"])


def test_trigger_refuses_a_symlinked_target(tmp_path: Path) -> None:
    real = tmp_path / "notice.json"
    real.write_bytes(notice_with("MS181101ab"))
    link = tmp_path / "link.json"
    link.symlink_to(real)
    assert classify(str(real))[0] == "notice"
    with pytest.raises(InputError, match="symbolic link"):
        classify(str(link))


def test_state_and_trigger_files_are_private(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        state = tmp_path / "home" / "state.sqlite"
        state.parent.mkdir()
        Store(state).close()
        assert stat.S_IMODE(state.stat().st_mode) == 0o600
        tdir = tmp_path / "home" / "triggers"
        f = write_trigger(tdir, "notice", b"{}")
        assert stat.S_IMODE(tdir.stat().st_mode) == 0o700
        assert stat.S_IMODE(f.stat().st_mode) == 0o600
        Store(tmp_path / "g.sqlite", group_readable=True).close()
        assert stat.S_IMODE((tmp_path / "g.sqlite").stat().st_mode) == 0o640
    finally:
        os.umask(old)


def test_rejected_messages_keep_only_a_prefix_and_are_pruned(tmp_path: Path) -> None:
    p = _pipeline(tmp_path / "s.sqlite")
    junk = b"{" + os.urandom(2_000_000)
    acc = p.accept(junk, "attack:junk", received_at())
    assert acc.action == "rejected"
    (size, kept) = p.store.connection().execute("SELECT size, length(raw) FROM notices").fetchone()
    assert size == len(junk) and kept == 1024
    planned = p.accept(notice_with("MS181101ab"), "attack:ok", received_at())
    assert p.store.prune_raw(older_than_s=0) == 1
    assert p.store.notice_raw(acc.notice_id) is None
    assert p.store.notice_raw(planned.notice_id) is not None  # a job's map is never pruned


# ---------------------------------------------------------------- 8. retries after the store closed
def test_no_outbox_retry_touches_the_store_once_it_is_closed(tmp_path: Path, caplog) -> None:
    import time

    from mushrooms.daemon.drain import OutboxDrain
    from mushrooms.daemon.service import Service

    config = _service_config(None, outbox=str(tmp_path / "out"), state=str(tmp_path / "s.sqlite"))
    svc = Service(config, resolve_paths(config.daemon))
    svc.pipeline = _pipeline(tmp_path / "s.sqlite")
    svc.outbox = OutboxDrain(svc._flush_outbox, 0.1, 1.0)
    try:
        svc._close_store(svc.pipeline.store.close)
        svc.outbox.kick(now=True)  # a publish attempt after the store is closed
        deadline = time.monotonic() + 30.0
        while svc.outbox.attempts < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert svc.outbox.attempts >= 1
        assert svc.outbox.failures == 0 and not svc.outbox.retry_scheduled
    finally:
        svc.outbox.close()
    assert "publish_failed" not in caplog.text and "closed database" not in caplog.text


# ---------------------------------------------------------------- 9. a plan is told before its submission's trouble
class _SlowPublisher:
    """The pipeline's outbox pass, as slow as a busy disk: what it published, and when, goes to ``told``."""

    def __init__(self, told: list[str], fail_first: bool = False) -> None:
        self.told, self.fail_first = told, fail_first

    def flush_outbox(self) -> int:
        if self.fail_first:  # the outbound broker is down: the pass fails, the drain backs off
            self.fail_first = False
            raise ConnectionError("broker down")
        time.sleep(0.5)
        self.told.append("plan_published")
        return 0


def _service_with(tmp_path: Path, told: list[str], fail_first: bool = False, retry_s: float = 0.1):
    from mushrooms.daemon.drain import OutboxDrain
    from mushrooms.daemon.service import Service

    config = _service_config(None, outbox=str(tmp_path / "out"), state=str(tmp_path / "s.sqlite"))
    svc = Service(config, resolve_paths(config.daemon))
    svc.pipeline = _SlowPublisher(told, fail_first)
    svc.outbox = OutboxDrain(svc._flush_outbox, retry_s, retry_s, name="outbox")
    svc.submit_drain = OutboxDrain(lambda: told.append("submission_failing") or 0, 0.1, 1.0, name="submit")
    return svc


def _until(predicate, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.01)


def test_a_plan_is_published_before_its_submission_is_tried(tmp_path: Path) -> None:
    """The CI run of 2026-12-06 told the webhook "could not be submitted" before "new plan" (a fast submitter)."""
    told: list[str] = []
    svc = _service_with(tmp_path, told)
    try:
        svc.queued()  # a plan was stored: publish it, then submit it
        _until(lambda: "submission_failing" in told and "plan_published" in told)
    finally:
        svc.outbox.close()
        svc.submit_drain.close()
    assert told[:2] == ["plan_published", "submission_failing"], told


def test_a_submission_does_not_wait_for_an_outbound_broker_that_is_down(tmp_path: Path) -> None:
    told: list[str] = []
    svc = _service_with(tmp_path, told, fail_first=True, retry_s=60.0)
    try:
        svc.outbox.kick()  # an earlier message: the pass fails, the outbox backs off for 60 s
        # (the failed pass kicked the submitter too: wait for that pass before counting)
        _until(lambda: svc.outbox.retry_scheduled and svc.submit_drain.attempts >= 1 and bool(told))
        assert svc.outbox.retry_scheduled and told == ["submission_failing"]
        told.clear()
        svc.queued()  # a plan is stored during the back-off: ZTF's queue does not wait 60 s for our broker
        _until(lambda: "submission_failing" in told, 10.0)
    finally:
        svc.outbox.close()
        svc.submit_drain.close()
    assert told == ["submission_failing"], told


# ---------------------------------------------------------------- the unit
def test_the_unit_sets_limits_and_scores_at_most_1_5(tmp_path: Path) -> None:
    unit = (REPO / "systemd" / "mushrooms.service").read_text()
    for key in ("MemoryMax=", "TasksMax=", "RestartPreventExitStatus="):
        assert any(line.startswith(key) for line in unit.splitlines()), key
    tool = shutil.which("systemd-analyze")
    if tool is None:
        pytest.skip("systemd-analyze is not installed here")
    r = subprocess.run([tool, "security", "--offline=yes", str(REPO / "systemd" / "mushrooms.service")],
                       capture_output=True, text=True, timeout=120)
    line = next(x for x in (r.stdout + r.stderr).splitlines() if "Overall exposure level" in x)
    score = float(line.split(":")[1].split()[0])
    assert score <= 1.5, line
