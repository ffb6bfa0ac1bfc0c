"""The queue names an observer is shown are the names ZTF's queue holds (issue 52, finding 9).

The daemon's own wiring (``open_pipeline``: the store, the outbox directory
with its ``.txt``/``.html`` summaries) plans a real notice with the greedy
scheduler; its submitter PUTs the revision's queue set to the Kowalski
contract server on loopback; the names in the outbox summary, on the page
and in ``mushrooms status`` must be exactly the names the server holds.
The command-line side (``plan --queue``, ``submit --dry-run``) is in
``tests/test_cli_queue_names.py``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from contract_servers import KowalskiContract
from daemon_helpers import directory_outbox_config, notice_bytes
from mushrooms.daemon.settings import resolve_paths
from mushrooms.daemon.submission.remote import make_client
from mushrooms.daemon.submission.submitter import Submitter
from mushrooms.daemon.wiring import open_pipeline
from mushrooms.tool import status
from mushrooms.tool.config import load_config

TOKEN = "queue-names-t0ken-4e5f6a7b8c9d"
SID = "MS181101ab"


def _config(tmp_path: Path, url: str, target: str = "kowalski") -> Path:
    path = tmp_path / "config.toml"
    path.write_text(directory_outbox_config(tmp_path) + f"""

[submit]
target = "{target}"
url = "{url}"
timeout_s = 3.0
""")
    return path


def _shown_names(text: str) -> list[str]:
    """Every queue name a text shows (``ToO_...``)."""
    return re.findall(r"\bToO_[A-Za-z0-9_.-]+", text)


@pytest.fixture
def kowalski(loopback):
    return KowalskiContract(loopback, TOKEN)


def _run(cfg_path: Path, kowalski_url: str, target: str = "kowalski"):
    config = load_config(str(cfg_path))
    pipeline, close = open_pipeline(config, resolve_paths(config.daemon))
    out = pipeline.handle(notice_bytes(f"{SID}-preliminary.json"), "test:queue-names")
    assert out.decision == "plan", out
    if target != "none":  # the daemon runs no submitter without a target
        client = make_client(target, kowalski_url, TOKEN, 3.0)
        Submitter(pipeline.store, config.submit, config.export, client).step()
        pipeline.flush_outbox()  # the submission documents too
    return config, pipeline, close


def test_the_outbox_summary_page_and_status_show_the_queues_kowalski_holds(tmp_path, kowalski, capsys) -> None:
    cfg = _config(tmp_path, kowalski.url)
    config, pipeline, close = _run(cfg, kowalski.url)
    try:
        held = list(kowalski.queues)
        assert len(held) >= 2  # a set: one queue per filter pass
        pipeline.sink.close()  # the names and the pages: on the summary thread
        (plan_json,) = [p for p in (tmp_path / "outbox").glob("mushrooms-*.json") if p.stem.count("-") == 1]
        txt = plan_json.with_suffix(".txt").read_text()
        queue_lines = [line for line in txt.splitlines() if line.startswith("Queue")]
        assert queue_lines, txt
        shown = _shown_names("\n".join(queue_lines))
        assert shown[0] == held[0] and shown[-1] == held[-1], (queue_lines, held)
        assert set(shown) <= set(held)
        assert f"{len(held)} queues" in queue_lines[0]
        assert "submitted to kowalski" in queue_lines[0]  # written again when the submission document came
        page = plan_json.with_suffix(".html").read_text()
        assert _shown_names(page) == held, (_shown_names(page), held)
    finally:
        close()
    capsys.readouterr()
    status.main(["--state", str(tmp_path / "state.sqlite"), "--config", str(cfg)])
    said = capsys.readouterr().out
    lines = [line for line in said.splitlines() if line.strip().startswith("Queue")]
    assert lines and _shown_names(lines[0])[0] == held[0] and _shown_names(lines[0])[-1] == held[-1], said
    assert "submitted" in lines[0]


def test_without_a_target_the_summary_names_the_queues_it_would_submit(tmp_path, kowalski) -> None:
    cfg = _config(tmp_path, kowalski.url, target="none")
    config, pipeline, close = _run(cfg, kowalski.url, target="none")
    close()
    assert not kowalski.queues
    (plan_json,) = [p for p in (tmp_path / "outbox").glob("mushrooms-*.json") if p.stem.count("-") == 1]
    doc = json.loads(plan_json.read_text())
    line = next(x for x in plan_json.with_suffix(".txt").read_text().splitlines() if x.startswith("Queue"))
    assert "not submitted" in line and "[submit] target" in line, line
    from mushrooms.scheduler_core import Plan
    from mushrooms.scheduler_core.plan.exports import queue_name_base, to_trigger_queues

    base = queue_name_base(config.export.subprogram_name, doc["plan_id"], SID)
    names = [q["queue_name"] for q in to_trigger_queues(Plan.from_document(doc), config.export, base)]
    assert _shown_names(line)[0] == names[0] and _shown_names(line)[-1] == names[-1]


# -- the webhook and ``status``'s attention lines name each queue (the name base is no queue's name) --------------

def _expected_few(names: list[str], most: int = 3) -> str:
    """The first ``most`` names, then ``+N more``: what a one-line message shows of a set."""
    return ", ".join(names[:most]) + (f" +{len(names) - most} more" if len(names) > most else "")


def _submission_documents(outbox: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(outbox.glob("*-submission-*.json"))]


def test_the_webhook_names_the_queues_kowalski_holds_not_their_name_base(tmp_path, kowalski) -> None:
    from mushrooms.daemon.ops.announce import announcement

    cfg = _config(tmp_path, kowalski.url)
    config, pipeline, close = _run(cfg, kowalski.url)
    close()
    held = list(kowalski.queues)
    (doc,) = [d for d in _submission_documents(tmp_path / "outbox") if d["state"] == "submitted"]
    kind, text = announcement(doc)
    assert kind == "submission_submitted"
    assert text.startswith(f"{SID}: queues {_expected_few(held)} (kowalski) is in ZTF's queue"), (text, held)
    base = doc["queue_name"]
    assert f"{base} " not in text and f"{base} (" not in text  # the base alone names no queue


def test_a_webhook_message_names_a_few_queues_of_a_large_set_then_how_many_more() -> None:
    from mushrooms.daemon.ops.announce import NotifyingSink, announcement, submission_trouble
    from mushrooms.daemon.submission.rows import Submission, status_document

    base = "ToO_GW_S250101a_0123456789ab"
    body = [{"queue_name": f"{base}_{k}", "targets": [], "validity_window_mjd": [1.0, 2.0]} for k in range(1, 8)]
    sub = Submission("mushrooms-0123456789abcdef", "S250101a", "kowalski", 1, base, "submitted", None, body,
                     None, 200, None, 1, "2026-01-01T00:00:00Z", None, None, None)
    _, text = announcement(status_document(sub))
    assert f"queues {base}_1, {base}_2, {base}_3 +4 more (kowalski) is in ZTF's queue" in text, text
    assert f"{base}_4" not in text and len(text) < 300

    class Hook:
        said: list = []

        def post(self, kind, text, details=None):
            self.said.append((kind, text, details))
            return True

    hook = Hook()
    submission_trouble(NotifyingSink(None, hook), sub.superevent_id, sub.queue_names(), 1, "HTTP 500")
    (kind, text, details), = hook.said
    assert text.startswith(f"S250101a: queues {base}_1, {base}_2, {base}_3 +4 more could not be submitted"), text
    assert details["queue_names"] == [q["queue_name"] for q in body]
    from mushrooms.daemon.ops.webhook import webhook_body

    hostile = json.loads(webhook_body("json", kind, text, {"queue_names": ["<!channel> ToO_x"] * 80}))
    assert len(hostile["queue_names"]) == 50 and "<!channel>" not in json.dumps(hostile)  # bounded, neutralised


def test_status_and_readiness_name_the_queues_of_a_submission_pending_too_long(tmp_path, capsys) -> None:
    import socket
    import time

    from mushrooms.daemon.ops.health import submission_check
    from mushrooms.daemon.submission.rows import submissions

    dead = socket.socket()
    dead.bind(("127.0.0.1", 0))  # bound, never listening: connection refused
    url = f"http://127.0.0.1:{dead.getsockname()[1]}"
    try:
        config, pipeline, close = _run(_config(tmp_path, url), url)
        (row,) = [s for s in submissions(pipeline.store) if s.state == "pending"]
        past = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(time.time() - 3600)) + ".000+00:00"
        with pipeline.store.transaction() as c:
            c.execute("UPDATE submissions SET created_at=?", (past,))
        close()
    finally:
        dead.close()
    names = row.queue_names()
    assert len(names) >= 2 and all(n.startswith(f"{row.queue_name}_") for n in names)
    limit = tmp_path / "limit.toml"
    limit.write_text("[submit]\nmax_pending_s = 600\n")
    capsys.readouterr()
    assert status.main(["--state", str(tmp_path / "state.sqlite"), "--config", str(limit)]) == 1
    said = capsys.readouterr().out
    (line,) = [x for x in said.split("NEEDS ATTENTION")[-1].splitlines() if "pending for" in x]
    assert f"queues {_expected_few(names)})" in line, (line, names)
    assert _shown_names(line) == names[:3], line

    class Drain:
        retry_scheduled = False

    ok, detail = submission_check(tmp_path / "state.sqlite", Drain(), max_pending_s=600.0)()
    assert not ok and detail.startswith(f"queues {_expected_few(names)} pending for"), detail
