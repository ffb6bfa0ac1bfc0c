"""``mushrooms demo``: the bundled mock BNS notice planned end to end through the service's own path."""

from __future__ import annotations

import argparse
import sys
import json
from pathlib import Path
from typing import Sequence

from .common import SOLVER_CHOICES, SOLVER_HELP, SOLVER_METAVAR, add_common_options, execute, tool_parser

__all__ = ["HELP", "parser", "run", "main"]

HELP = "plan the bundled mock BNS notice end to end (no credentials, no network)"

def parser(p: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """The options of ``mushrooms demo`` (added to ``p``, or to a new parser)."""
    p = p if p is not None else tool_parser("demo", HELP)
    p.add_argument("--out", metavar="DIR", default="mushrooms-demo",
                   help="where the plan, its picture and the state go (default mushrooms-demo)")
    p.add_argument("--solver", choices=SOLVER_CHOICES, metavar=SOLVER_METAVAR, help=SOLVER_HELP)
    add_common_options(p)
    return p


def main(args: Sequence[str] | None = None) -> int:
    """``mushrooms demo`` on its own."""
    return execute("demo", parser().parse_args(args), run)


def run(args: argparse.Namespace) -> int:
    """Replay the bundled mock notice through the daemon's own path, then draw the plan.

    Writes the plan document, a picture of it and the SQLite state into
    ``--out``; needs no credentials and no network.
    """
    import base64

    from ..bundled import demo_notice_path
    from .config import load_config
    from ..daemon.intake.replay import replay_notices
    from ..offline import configure_astropy_offline
    from .overrides import override_config
    from ..plotting import plot_plan
    from ..scheduler_core import Plan, read_skymap

    configure_astropy_offline()
    config = override_config(load_config(args.config), allow_mock=True, solver=args.solver)  # a bad config fails here
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    notice = demo_notice_path()
    from .replay import print_outcome, print_summary

    report = replay_notices([notice], out / "outbox", config, state=out / "state.sqlite", on_outcome=print_outcome)
    print_summary(report, "demo")
    code = report.status
    from ..report.files import revision_in_force

    doc = revision_in_force(json.loads(p.read_text()) for p in sorted((out / "outbox").glob("*.json")))
    if doc is None:
        print(f"demo: no plan was produced (replay exit status {code}); see the log above")
        return 1
    plan = Plan.from_document(doc)
    payload = json.loads(Path(notice).read_text())["event"]["skymap"]
    skymap = read_skymap(base64.b64decode(payload), nside=config.scheduler.nside)
    picture = out / "plan.png"
    plot_plan(plan, skymap, picture)
    from ..report.files import write_summaries
    from ..report.summary import answer_line, summary_text

    txt, page = write_summaries(doc, out / "plan.json", picture.read_bytes())
    print()
    print(summary_text(doc, rows=False))
    print(f"demo: {plan.event.superevent_id}: {answer_line(doc)}")
    print(f"demo: plan in {out / 'outbox'}, picture {picture}, summary {txt} (one row per exposure), page {page}")
    print(f"demo: look at it as the service's operator would: mushrooms status --state {out / 'state.sqlite'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
