"""Big flat sky maps through ``mushrooms plan``: peak RSS, wall time, the same plan as the multi-order map.

Makes flat four-column maps (PROB, DISTMU, DISTSIGMA, DISTNORM) at NSIDE
1024 and 2048 from one real multi-order BAYESTAR map (the LVK user-guide's
observing-scenarios event 800, orders up to 11, 22.9 deg2 at 90 %, observable by ZTF from
its merger time: the bundled MS181101ab is 22 deg from the Sun) with ligo.skymap's ``bayestar.rasterize``
(exact at order 11; moments at 10), NESTED and RING (healpy's reorder),
plain and gzipped, then runs each through ``mushrooms plan`` under
``/usr/bin/time -v`` in a fresh interpreter and compares the plan's
observations with those planned from the multi-order file itself.  Then
three bombs (a header declaring NSIDE 2^20, the plain NSIDE 1024 map cut in
half, the gzipped NSIDE 1024 map followed by 1 GiB of zeros) must each be
one line, exit 2.

    PYTHONPATH=$PWD python benchmarks/speed/skymap_memory.py [--work DIR] [--out benchmarks/results/speed/skymap_memory]
        [--old-python /work/main/.venv/bin/python --old-path /work/main]

Maps are written to ``--work`` (about 4.5 GB; not committed); results are
``OUT/skymap_memory.json`` and ``OUT/skymap_memory.md``.
"""

from __future__ import annotations

import argparse
import gzip
import json
import os
import re
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
MOC = Path("/work/shared/data/skymaps/public/obs-scenarios_sim800_HKL.multiorder.fits")
COLUMNS = ("PROB", "DISTMU", "DISTSIGMA", "DISTNORM")


def make_flat(work: Path, order: int) -> dict[str, Path]:
    """NESTED/RING x plain/gzip flat maps at ``order`` from the multi-order map."""
    import healpy as hp
    from astropy.io import fits
    from ligo.skymap.bayestar import rasterize
    from ligo.skymap.io import read_sky_map

    nside = 1 << order
    out = {f"{o}{'.gz' if z else ''}": work / f"flat{nside}_{o}.fits{'.gz' if z else ''}"
           for o in ("nested", "ring") for z in (False, True)}
    if all(p.exists() for p in out.values()):
        return out
    table = rasterize(read_sky_map(str(MOC), moc=True), order=order)
    header = fits.getheader(MOC, 1)
    for ordering in ("nested", "ring"):
        cols = []
        for c in COLUMNS:
            v = np.asarray(table[c], float)
            cols.append(fits.Column(name=c, format="D", array=v if ordering == "nested" else hp.reorder(v, n2r=True)))
        hdu = fits.BinTableHDU.from_columns(cols)
        for key in ("OBJECT", "DATE-OBS", "MJD-OBS", "DISTMEAN", "DISTSTD", "INSTRUME", "CREATOR"):
            if key in header:
                hdu.header[key] = header[key]
        hdu.header.update({"PIXTYPE": "HEALPIX", "ORDERING": ordering.upper(), "COORDSYS": "C", "NSIDE": nside,
                           "INDXSCHM": "IMPLICIT"})
        plain = out[ordering]
        fits.HDUList([fits.PrimaryHDU(), hdu]).writeto(plain, overwrite=True)
        del cols, hdu
        with open(plain, "rb") as src, gzip.open(out[f"{ordering}.gz"], "wb", compresslevel=6) as dst:
            while block := src.read(1 << 24):
                dst.write(block)
    return out


def make_bombs(work: Path, flat1024: dict[str, Path]) -> dict[str, Path]:
    from astropy.io import fits

    bombs = {"header NSIDE 2^20": work / "bomb_nside2p20.fits.gz", "truncated (half)": work / "bomb_truncated.fits",
             "gzip + 1 GiB past its table": work / "bomb_grown.fits.gz"}
    h = fits.Header()
    for k, v in (("XTENSION", "BINTABLE"), ("BITPIX", 8), ("NAXIS", 2), ("NAXIS1", 8192), ("NAXIS2", 12 * 4**20 // 1024),
                 ("PCOUNT", 0), ("GCOUNT", 1), ("TFIELDS", 1), ("TTYPE1", "PROB"), ("TFORM1", "1024D"),
                 ("PIXTYPE", "HEALPIX"), ("ORDERING", "NESTED"), ("NSIDE", 2**20), ("INDXSCHM", "IMPLICIT")):
        h[k] = v
    bombs["header NSIDE 2^20"].write_bytes(gzip.compress(fits.PrimaryHDU().header.tostring().encode()
                                                         + h.tostring().encode() + bytes(1 << 20)))
    data = flat1024["nested"].read_bytes()
    bombs["truncated (half)"].write_bytes(data[: len(data) // 2])
    z = zlib.compressobj(6, zlib.DEFLATED, 31)
    with open(bombs["gzip + 1 GiB past its table"], "wb") as fh:
        for i in range(0, len(data), 1 << 24):
            fh.write(z.compress(data[i:i + (1 << 24)]))
        zeros = bytes(1 << 24)
        for _ in range(64):
            fh.write(z.compress(zeros))
        fh.write(z.flush())
    return bombs


def run_plan(path: Path, solver: str, out: Path, python: str, pythonpath: str) -> dict:
    env = dict(os.environ, PYTHONPATH=pythonpath)
    cmd = ["/usr/bin/time", "-v", python, "-m", "mushrooms.cli", "plan", str(path), "--solver", solver,
           "-o", str(out)]  # horizon from the map's DATE-OBS, copied into every flat map
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    # ``-m`` puts the working directory first on sys.path: run in the tree whose package is meant
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=pythonpath or REPO)
    wall = time.perf_counter() - t0
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr)
    doc = json.loads(out.read_text()) if r.returncode == 0 and out.exists() else {}
    lines = [ln for ln in r.stderr.splitlines() if ln.strip() and not ln.startswith("\t")
             and "Command being timed" not in ln]
    return {"map": path.name, "bytes": path.stat().st_size, "solver": solver, "exit": r.returncode,
            "wall_s": round(wall, 2), "max_rss_mb": round(int(rss.group(1)) / 1024, 1) if rss else None,
            "load1": round(load, 2), "stdout": r.stdout.strip()[-300:], "type": doc.get("type"),
            "n_obs": len(doc.get("observations", [])), "coverage": (doc.get("metrics") or {}).get("coverage"),
            "error": next((ln for ln in lines if "error" in ln.lower()), "") if r.returncode else ""}


def observations(plan: Path) -> list[tuple]:
    doc = json.loads(plan.read_text())
    return [(o.get("field_id"), o.get("filter"), o.get("start")) for o in doc.get("observations", [])]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=Path("/tmp/mushrooms-skymap-memory"))
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks/results/speed/skymap_memory")
    ap.add_argument("--old-python", default=None, help="interpreter of the code before the change (for 'before' rows)")
    ap.add_argument("--old-path", default=None, help="PYTHONPATH of the code before the change")
    ap.add_argument("--skip-2048", action="store_true")
    a = ap.parse_args()
    a.work.mkdir(parents=True, exist_ok=True)
    a.out.mkdir(parents=True, exist_ok=True)
    py, here = sys.executable, str(REPO)
    maps = {1024: make_flat(a.work, 10)}
    if not a.skip_2048:
        maps[2048] = make_flat(a.work, 11)
    rows = [dict(run_plan(MOC, "greedy", a.work / "plan_moc_greedy.json", py, here), nside="MOC")]
    ref = observations(a.work / "plan_moc_greedy.json")
    for nside, files in maps.items():
        for kind, path in files.items():
            plan = a.work / f"plan_{nside}_{kind}_greedy.json"
            row = dict(run_plan(path, "greedy", plan, py, here), nside=nside, layout=kind)
            row["same_plan_as_moc"] = row["exit"] == 0 and observations(plan) == ref
            rows.append(row)
            print(json.dumps(row), flush=True)
    # one hybrid run: the multi-order map and the RING gzip NSIDE 1024 map
    hyb = [dict(run_plan(MOC, "hybrid", a.work / "plan_moc_hybrid.json", py, here), nside="MOC")]
    plan = a.work / "plan_1024_ring_hybrid.json"
    row = dict(run_plan(maps[1024]["ring.gz"], "hybrid", plan, py, here), nside=1024, layout="ring.gz")
    row["same_plan_as_moc"] = row["exit"] == 0 and observations(plan) == observations(a.work / "plan_moc_hybrid.json")
    hyb.append(row)
    print(json.dumps(row), flush=True)
    bombs = []
    for what, path in make_bombs(a.work, maps[1024]).items():
        row = dict(run_plan(path, "greedy", a.work / "plan_bomb.json", py, here), bomb=what)
        bombs.append(row)
        print(json.dumps(row), flush=True)
    before = []
    if a.old_python:
        for kind in ("nested", "nested.gz"):
            row = dict(run_plan(maps[1024][kind], "greedy", a.work / "plan_old.json", a.old_python, a.old_path or ""),
                       nside=1024, layout=kind, code="before")
            before.append(row)
            print(json.dumps(row), flush=True)
    report = {"moc": str(MOC), "greedy": rows, "hybrid": hyb, "bombs": bombs, "before": before}
    (a.out / "skymap_memory.json").write_text(json.dumps(report, indent=1))
    md = ["| map | layout | bytes | exit | observations | coverage | max RSS MB | wall s | load | same plan as MOC |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows + hyb + before:
        md.append(f"| {r.get('nside')} {r['solver']}{' (before)' if r.get('code') else ''} | {r.get('layout', '-')} | "
                  f"{r['bytes']} | {r['exit']} | {r['n_obs']} | {r['coverage']} | {r['max_rss_mb']} | {r['wall_s']} | "
                  f"{r['load1']} | {r.get('same_plan_as_moc', '-')} |")
    md += ["", "| bomb | bytes | exit | max RSS MB | wall s | load | message |", "|---|---|---|---|---|---|---|"]
    for r in bombs:
        md.append(f"| {r['bomb']} | {r['bytes']} | {r['exit']} | {r['max_rss_mb']} | {r['wall_s']} | {r['load1']} | "
                  f"{r['error'][:160]} |")
    (a.out / "skymap_memory.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
