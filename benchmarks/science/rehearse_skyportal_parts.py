"""A rehearsal of the real service with ZTF and WINTER, ``[submit_parts]`` on, against a SkyPortal on loopback.

``mushrooms rehearse`` (the loopback broker, the real daemon) plans MS181101ab's
PRELIMINARY made live with ``telescopes = ["ztf", "winter"]``; WINTER's part
(``queue = "skyportal"``) is POSTed by the service's ``submit_parts`` thread to a
contract server (pytest-httpserver on 127.0.0.1, the tests' ``PartsSkyPortal``).
Prints the rehearsal's verdict, the outbox's files, the requests SkyPortal got
and the state file's ``part_requests`` rows.  Issue 53 item 4.

Usage: ``python benchmarks/science/rehearse_skyportal_parts.py OUT_DIR``
"""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTICE = ROOT / "tests" / "data" / "notices" / "json" / "MS181101ab-preliminary.json"


def main(out: Path) -> int:
    sys.path[:0] = [str(ROOT / "tests" / "daemon"), str(ROOT)]
    from contract_servers import loopback_server
    from part_requests_setup import TOKEN, PartsSkyPortal

    server = loopback_server()
    skyportal = PartsSkyPortal(server)
    out.mkdir(parents=True, exist_ok=True)
    cfg = out / "config.toml"
    cfg.write_text('[scheduler]\nsolver = "greedy"\nnside = 64\ntelescopes = ["ztf", "winter"]\n\n'
                   '[daemon]\nheartbeat_s = 2\n\n'
                   f'[submit_parts]\nenabled = true\nurl = "{skyportal.url}"\nallocations = {{ winter = 7 }}\n'
                   'timeout_s = 5.0\nretry_initial_s = 0.5\nretry_max_s = 2.0\n')
    env = {k: v for k, v in os.environ.items() if not k.startswith("MUSHROOMS_SUBMIT")}
    env.update(PYTHONPATH=str(ROOT), MUSHROOMS_SKYPORTAL_TOKEN=TOKEN)
    try:
        r = subprocess.run([sys.executable, "-m", "mushrooms.cli", "rehearse", str(NOTICE), "--config", str(cfg),
                            "--out", str(out / "rehearsal")], capture_output=True, text=True, env=env, cwd=out,
                           timeout=1200)
    finally:
        server.stop()
    print(f"rehearse exit {r.returncode}")
    print("\n".join(line for line in r.stdout.splitlines() if "rehearsal" in line or "telescope part" in line))
    outbox = out / "rehearsal" / "outbox"
    print("outbox:")
    for p in sorted(outbox.rglob("*")):
        if p.is_file():
            print(f"  {p.relative_to(outbox)}  {p.stat().st_size} bytes")
    print("SkyPortal got:")
    for e in skyportal.log:
        print(f"  {e['method']} {e['path']} -> {e['status']} plan_name={e.get('plan_name', '-')}")
    for pid, body in skyportal.plans.items():
        planned = body["observation_plans"][0]["planned_observations"]
        print(f"  stored request {pid}: allocation {body['allocation_id']}, {len(planned)} planned observations, "
              f"filters {sorted({o['filt'] for o in planned})}, window {body['payload']['start_date']} .. "
              f"{body['payload']['end_date']}")
    states = sorted((out / "rehearsal").rglob("*.sqlite"))
    for state in states:
        with sqlite3.connect(state) as conn:
            rows = conn.execute("SELECT job_id, telescope, plan_name, state, remote_id, attempts, reason "
                                "FROM part_requests").fetchall()
        print(f"part_requests in {state.name}: {json.dumps(rows)}")
    leaked = [str(p) for p in out.rglob("*") if p.is_file() and p.name != "config.toml"
              and TOKEN.encode() in p.read_bytes()] + (["rehearse output"] if TOKEN in r.stdout + r.stderr else [])
    print(f"token found in: {leaked or 'nothing'}")
    if r.returncode != 0:
        print(r.stdout[-3000:], r.stderr[-3000:])
    return r.returncode


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
