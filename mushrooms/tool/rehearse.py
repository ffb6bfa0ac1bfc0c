"""``mushrooms rehearse [NOTICE]``: check a configuration before an event, end to end, in one command.

A rehearsal starts a Kafka-protocol broker on loopback (librdkafka's mock
cluster, :mod:`.loopback_broker`), starts the service (``mushrooms run``, a
process of its own) with the user's configuration, sends it a live copy of
the notice (the bundled mock BNS notice by default; :mod:`.live_notice`
moves its clocks to now, so the policy takes it as new) and tells what
happens, line by line in words (:mod:`.rehearse_watch`), until the plan is
final: revision 1, then the optimised revision or the ``plan_final``
verdict.  Then it stops the service (SIGTERM) and prints the plan's summary.

Everything the configuration points at is used as configured: the
scheduler, the policy, ``[submit]`` (``--dry-run`` makes the submission a
dry run), ``[loop]``, ``[notify]``.  Only what a rehearsal must own is
replaced: the input broker (the loopback one), the outbox (a directory),
the state, trigger, pid and quarantine paths (all in ``--out``, default a
new temporary directory) and the metrics listener (off, so a running
service's port is not taken).

Exit status: 0 the plan became final and the service stopped cleanly; 1 the
service failed, refused the notice, its warm-up plan or the notice's planning
job failed, or the plan did not become final within ``--timeout`` (one line
says which); 2 bad input (``--timeout`` not in (0, 86400] s included).
Without ``--out`` the temporary directory is removed when the rehearsal
passes and kept when it fails.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, Sequence

from .common import add_common_options, execute, tool_parser
from .rehearsal import say
from .settings_flag import add_set_option

__all__ = ["HELP", "parser", "run", "main", "service_command"]

HELP = "rehearse an alert: a local broker, the service with your config, a live notice, until the plan is final"

#: Longest ``--timeout`` (s): a day; a rehearsal still waiting then has hung.
MAX_TIMEOUT_S = 86400.0

#: What a rehearsal owns in the configuration (``--set`` after the user's, so they win).
REHEARSAL_SETS = ("daemon.trigger_dir=\"triggers\"", "daemon.pid_file=\"mushrooms.pid\"",
                  "daemon.quarantine_dir=\"quarantine\"", "daemon.metrics_address=\"\"",
                  "kafka.offset_reset=\"earliest\"")


def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms rehearse`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("rehearse", HELP)
    p.add_argument("notice", nargs="?", metavar="NOTICE",
                   help="an IGWN notice in JSON (default: the bundled mock BNS notice MS260605l)")
    p.add_argument("--out", metavar="DIR", help="state, outbox and the service's log (default: a new temporary "
                                                 "directory, printed)")
    p.add_argument("--timeout", type=float, default=900.0, metavar="S",
                   help="give up when the plan is not final this long after the service was started (default 900, "
                        f"at most {MAX_TIMEOUT_S:g})")
    p.add_argument("--dry-run", action="store_true",
                   help="submission as a dry run (the request logged, token as ***), whatever [submit] says")
    add_set_option(p)
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms rehearse`` on its own."""
    return execute("rehearse", parser().parse_args(args), run)


def _out_dir(given: str | None) -> Path:
    import tempfile

    from ..scheduler_core.errors import InputError

    if given is None:
        return Path(tempfile.mkdtemp(prefix="mushrooms-rehearse-"))
    out = Path(given).expanduser()
    if (out / "state.sqlite").exists():
        raise InputError(f"--out {given}: already holds a rehearsal's state; give a new directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {given}: cannot create it ({exc.strerror or exc})") from None
    return out


def _notice_bytes(given: str | None) -> tuple[str, bytes]:
    from ..bundled import demo_notice_path
    from ..inputs import read_regular_file

    path = given or demo_notice_path()
    return path, read_regular_file(path, 64 * 1024 * 1024, what="notice")


#: The service's interpreter start: on Linux it asks for SIGTERM when its parent (the rehearsal) dies, even
#: of SIGKILL (``PR_SET_PDEATHSIG`` = 1), and leaves at once if the parent is already gone; then ``mushrooms``.
_DIE_WITH_PARENT = """
import ctypes, os, signal, sys
parent = int(sys.argv.pop(1))
try:
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)
except (OSError, AttributeError):
    pass
if os.getppid() != parent:
    sys.exit(1)
from mushrooms.cli import main
sys.exit(main(sys.argv[1:]))
"""


def service_command(args: argparse.Namespace, bootstrap: str, out: Path) -> list[str]:
    """The ``mushrooms run`` command line of the rehearsal's service (it stops when the rehearsal dies)."""
    import os

    cmd = [sys.executable, "-c", _DIE_WITH_PARENT, str(os.getpid()), "--log-level", "INFO", "run"]
    if getattr(args, "config", None):
        cmd += ["--config", str(Path(args.config).resolve())]
    sets = list(getattr(args, "set", None) or ()) + list(REHEARSAL_SETS)
    if args.dry_run:
        sets.append("submit.dry_run=true")
    for s in sets:
        cmd += ["--set", s]
    return cmd + ["--bootstrap", bootstrap, "--outbox", str(out / "outbox"), "--state", str(out / "state.sqlite"),
                  "--allow-mock"]


def _describe_config(config: Any, args: argparse.Namespace, t0: float) -> None:
    from ..handlers.secret_text import strip_userinfo

    sched, submit, loop, notify = config.scheduler, config.submit, config.loop, config.notify
    budget = "" if sched.solver == "greedy" else f" ({sched.time_limit_s:g} s)"
    say(f"configuration {config.source}: solver {sched.solver}{budget}, objective {sched.objective}, "
        f"nside {sched.nside}", t0)
    if submit.enabled:
        dry = args.dry_run or submit.dry_run
        say(f"submission: {submit.target} at {strip_userinfo(submit.url)}"
            + (" as a DRY RUN" if dry else " -- REAL requests will be sent"), t0)
    else:
        say("submission: off ([submit] target = \"none\")", t0)
    source = strip_userinfo(loop.executed_source)
    say(f"loop: {'on, executed exposures from ' + source if loop.enabled else 'off'}; notifications: "
        + (f"{notify.target} webhook" if notify.enabled else "off"), t0)
    if config.outbound.sink != "directory":
        say(f"outbound: [outbound] sink = \"{config.outbound.sink}\" is replaced by the rehearsal's outbox", t0)


def run(args: argparse.Namespace) -> int:
    """Rehearse; the exit status (0 the plan became final and the service stopped cleanly)."""
    from ..scheduler_core.errors import InputError
    from .live_notice import live_copy
    from .overrides import effective_config

    if not (0.0 < args.timeout <= MAX_TIMEOUT_S):  # nan and inf too: a rehearsal that never ends
        raise InputError(f"--timeout must be a number of seconds in (0, {MAX_TIMEOUT_S:g}], got {args.timeout:g}")
    config = effective_config(args)  # a bad config or --set is one line, exit 2, before anything starts
    name, raw = _notice_bytes(args.notice)
    live_copy(raw)  # a notice that cannot be copied is refused before the service starts
    from ..daemon.ops.webhook_url import notify_url_usable

    notify_url_usable(config.notify)  # a webhook URL that is missing or cannot be used: refused, never shown
    out = _out_dir(args.out)
    t0 = time.monotonic()
    say(f"rehearsal in {out}" + ("" if args.out else " (a temporary directory: removed if the rehearsal passes, "
                                                     "kept if it fails)"), t0)
    _describe_config(config, args, t0)
    from .loopback_broker import BrokerError, LoopbackBroker
    from .rehearsal import Rehearsal

    try:
        with LoopbackBroker() as broker:
            for topic in config.kafka.topics:
                broker.ensure_topic(topic)
            say(f"loopback broker on {broker.bootstrap} (librdkafka's mock cluster), topic(s) "
                f"{', '.join(config.kafka.topics)}", t0)
            rehearsal = Rehearsal(service_command(args, broker.bootstrap, out), out, t0, args.timeout, config,
                                  temporary=args.out is None)
            status = rehearsal.run(lambda: _send(broker, config, name, raw, t0))
    except BrokerError as exc:
        print(f"mushrooms rehearse: error: {exc}", file=sys.stderr, flush=True)
        status = 1
    if args.out is None:
        _tidy(out, status, t0)
    return status


def _tidy(out: Path, status: int, t0: float) -> None:
    """Remove the rehearsal's temporary directory when it passed; keep it (and say where) when it did not."""
    import shutil

    if status == 0:
        shutil.rmtree(out, ignore_errors=True)
        say(f"removed the temporary directory {out}: give --out DIR to keep the plan and the service's log", t0)
    else:
        say(f"the rehearsal's files are kept in {out} (the service's log: {out / 'service.log'})", t0)


def _send(broker: Any, config: Any, name: str, raw: bytes, t0: float) -> None:
    """Send a live copy of the notice on the first input topic (its clocks moved to now)."""
    import json

    from .live_notice import live_copy

    live, times = live_copy(raw)
    sid = json.loads(live)["superevent_id"]
    broker.produce(config.kafka.topics[0], live, key=sid.encode())
    say(f"sent {Path(name).name} as a live notice: {sid}, created {times['created'][11:19]} UTC, merger "
        f"{times['merger'][11:19]} UTC (its clocks moved by {times['shift_s'] / 86400:.1f} days)", t0)


if __name__ == "__main__":
    sys.exit(main())
