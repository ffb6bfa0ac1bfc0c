"""Memory of five amplifying notices (a small notice whose maps unpack to 50 MB each).

Each notice is small on the wire but its GW map and its joint (combined) map
are the same gzipped *flat float32 NSIDE 1024* map: a real sky map
(tests/data/skymaps/MS220722v, rasterised by ligo.skymap at ``--order``)
upgraded to NSIDE 1024 NESTED the way ``healpy.ud_grade`` does (each pixel's
probability split evenly over its children), so it packs ~100x.  Five of
them, distinct superevents, are produced at once onto a 4-partition topic of
librdkafka's mock cluster and consumed by a real ``mushrooms run``
(``--tree``'s package) with the shipped scheduler settings (nside 256, hybrid)
and the default ``[daemon] max_jobs``.

Measured: the daemon's peak RSS (VmHWM of /proc/PID/status, polled; also the
largest VmRSS seen), the consume-loop time per notice (``store_s`` of the
``event=notice`` log line: receipt -> decision stored and committed), and what
was planned on which map (joint or GW).

    PYTHONPATH=$PWD nice -n 5 python benchmarks/speed/amplify_memory.py --tree $PWD --label after
"""

from __future__ import annotations

import argparse
import base64
import gzip
import io
import json
import re
import sqlite3
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "tests" / "daemon")]

from daemon_helpers import BROKER_SECTIONS, Broker, Daemon, notice_path  # noqa: E402

MOC = ROOT / "tests" / "data" / "skymaps" / "MS220722v_bayestar.multiorder.fits"

CONFIG = """
[scheduler]
min_coverage = 0.0

[policy]
allow_mock = true
max_notice_age_s = 0
max_event_age_s = 0

[daemon]
heartbeat_s = 5

"""
CONFIG += BROKER_SECTIONS


def amplifying_map(order: int) -> bytes:
    """gzip of a flat float32 NSIDE 1024 NESTED map: the real map at ``order``, upgraded to order 10."""
    import numpy as np
    from astropy.io import fits
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    prob = np.asarray(rasterize(read_sky_map(str(MOC), moc=True), order=order)["PROB"], float)
    k = 4 ** (10 - order)
    flat = (np.repeat(prob, k) / k).astype(np.float32)  # ud_grade, NESTED: children share the parent's probability
    hdu = fits.BinTableHDU.from_columns([fits.Column(name="PROB", format="E", array=flat)])
    hdu.header.update({"PIXTYPE": "HEALPIX", "ORDERING": "NESTED", "NSIDE": 1024, "INDXSCHM": "IMPLICIT",
                       "OBJECT": "amplify"})
    buf = io.BytesIO()
    fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(buf)
    return gzip.compress(buf.getvalue(), 9)


def status(pid: int) -> dict[str, int]:
    out = {}
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(("VmHWM:", "VmRSS:")):
                out[line.split(":")[0]] = int(line.split()[1])
    except OSError:
        pass
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", default=str(ROOT), help="tree whose mushrooms package the daemon runs")
    ap.add_argument("--label", default="after")
    ap.add_argument("--order", type=int, default=7, help="order of the real map before the upgrade to 10")
    ap.add_argument("--notices", type=int, default=5)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    out_path = Path(a.out or ROOT / "benchmarks" / "results" / "speed" / "amplify_memory" / f"amplify_memory_{a.label}.txt")
    work = Path(tempfile.mkdtemp(prefix="mushrooms-amp-"))
    load0 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    packed = amplifying_map(a.order)
    b64 = base64.b64encode(packed).decode()
    base = json.loads(notice_path("MS181101ab-ext-update.json").read_bytes())
    broker = Broker()
    topic, out_topic, group = broker.fresh_topics()
    cfg = work / "config.toml"
    cfg.write_text(CONFIG.format(topic=topic, out_topic=out_topic, group=group))
    state = work / "state.sqlite"
    d = Daemon(work, ["--config", str(cfg), "--bootstrap", broker.bootstrap, "--state", str(state)],
               env={"PYTHONPATH": a.tree})
    d.wait_log("event=service_ready", 300)
    idle = status(d.proc.pid)
    day = time.strftime("%y%m%d", time.gmtime())
    created = datetime.now(timezone.utc).replace(microsecond=0) - timedelta(minutes=10)
    sids = [f"MS{day}m{chr(97 + i)}" for i in range(a.notices)]
    sizes = []
    for i, sid in enumerate(sids):
        doc = json.loads(json.dumps(base))
        doc["superevent_id"] = sid
        doc["alert_type"] = "PRELIMINARY"
        doc["time_created"] = (created + timedelta(seconds=i)).strftime("%Y-%m-%dT%H:%M:%SZ")
        doc["event"]["skymap"] = b64
        doc["external_coinc"]["combined_skymap"] = b64
        raw = json.dumps(doc).encode()
        sizes.append(len(raw))
        broker.producer.produce(topic, value=raw, key=sid.encode(), partition=i % 4)
    assert broker.producer.flush(30) == 0
    t_sent = time.monotonic()
    hwm = rss = 0
    done_re = re.compile(r"event=job_done superevent_id=(\S+) job=\S+ (.*)")
    final_re = re.compile(r"job superevent_id=(\S+) job=\S+ decision=\S+ plan_id=\S+ revision=\d+ final=true")
    timeout = 1500
    while True:
        s = status(d.proc.pid)
        hwm, rss = max(hwm, s.get("VmHWM", 0)), max(rss, s.get("VmRSS", 0))
        text = d.text()
        finals = {m.group(1) for m in final_re.finditer(text)}
        failed = {m.group(1) for m in done_re.finditer(text) if "failed" in m.group(2) or "rejected" in m.group(2)}
        notices_logged = text.count("event=notice ")
        if notices_logged >= len(sids) and state.exists():
            with sqlite3.connect(f"file:{state}?mode=ro", uri=True) as c:
                n_jobs, n_open = c.execute("SELECT COUNT(*), SUM(status IN ('pending','running')) FROM jobs").fetchone()
            if n_jobs >= len(sids) and not n_open:
                break
        if d.proc.poll() is not None or time.monotonic() - t_sent > timeout:
            break
        time.sleep(0.2)
    wall = time.monotonic() - t_sent
    time.sleep(2)
    s = status(d.proc.pid)
    hwm = max(hwm, s.get("VmHWM", 0))
    alive = d.proc.poll() is None
    rc = d.stop() if alive else d.proc.returncode
    text = d.text()
    load1 = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    store_s = [float(x) for x in re.findall(r"event=notice .*?store_s=([0-9.]+)", text)]
    notice_lines = [ln for ln in text.splitlines() if "event=notice " in ln]
    loc = re.findall(r"job superevent_id=(\S+) job=\S+ decision=(\S+) plan_id=\S+ revision=(\d+) final=(\S+) "
                     r"coverage=([0-9.]+)", text)
    lines = [f"# benchmarks/speed/amplify_memory.py {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC, label {a.label}",
             f"# command: PYTHONPATH=$PWD nice -n 5 python benchmarks/speed/amplify_memory.py --tree {a.tree} "
             f"--label {a.label} --order {a.order} --notices {a.notices}",
             f"# daemon package: {a.tree}; shipped scheduler settings (nside 256, hybrid), max_jobs default",
             f"# uptime before: {load0}", f"# uptime after:  {load1}", "",
             f"map: flat float32 NSIDE 1024 NESTED (real map at order {a.order} upgraded), "
             f"{len(packed)} bytes gzipped, 50339520 unpacked",
             f"notices: {len(sids)} x {sizes[0]} bytes (GW map and combined map both that map)",
             f"daemon RSS when ready (before the notices): VmRSS {idle.get('VmRSS', 0) / 1024:.0f} MiB, "
             f"VmHWM {idle.get('VmHWM', 0) / 1024:.0f} MiB",
             f"daemon peak RSS (VmHWM) until every event had its final plan: {hwm / 1024:.0f} MiB "
             f"(largest VmRSS polled: {rss / 1024:.0f} MiB); the whole-map decode took 3.1 GB",
             f"consume-loop time per notice (store_s, receipt -> decision stored+committed): "
             f"{', '.join(f'{x:.2f}' for x in store_s)} s; the whole-map decode took 3-5 s",
             f"wall from produce to the last final plan: {wall:.0f} s; daemon alive at end: {alive}, exit {rc}",
             "", "notice lines:"] + [f"  {ln[ln.find('event=notice'):][:400]}" for ln in notice_lines]
    lines += ["", "plans (superevent, decision, revision, final, coverage):"]
    lines += [f"  {x}" for x in loc]
    with sqlite3.connect(f"file:{state}?mode=ro", uri=True) as c:
        jobs = c.execute("SELECT superevent_id, status, attempts, coverage, reason FROM jobs").fetchall()
        locs = c.execute("SELECT superevent_id, localization FROM events").fetchall()
    lines += ["", "jobs (superevent, status, attempts, coverage, reason):"] + [f"  {j}" for j in jobs]
    lines += ["events (superevent, localization planned on):"] + [f"  {x}" for x in locs]
    combined = text.count("combined map")
    lines += ["", f"log mentions of 'combined map': {combined}; 'planning on the GW map' fallbacks: "
              f"{text.count('planning on the GW map')}; Tracebacks: {text.count('Traceback')}; "
              f"MemoryError: {text.count('MemoryError')}"]
    out = "\n".join(lines) + "\n"
    print(out)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(out)
    out_path.with_suffix(".daemon.log").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
