"""Fill the on-disk cache of raw gwemopt schedules for a directory of sky maps.

gwemopt takes ~90 s per map; ``mushrooms bench`` with ``[bench]
gwemopt_cache_dir`` then scores its plans (raw and repaired) without
running it again.  One map at a time, in this process's order; maps already
cached are skipped.  Horizon start = the map's event time (as the bench's
default) unless ``--start``; planning options from ``--config`` (default:
the built-in defaults), so the keys match a bench run with the same config.

    MUSHROOMS_GWEMOPT_PYTHON=/path/to/python nice -n 10 \\
        .venv/bin/python benchmarks/science/gwemopt_cache.py ../shared/data/skymaps CACHE_DIR
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

from astropy.time import Time
from astropy.utils import iers

from mushrooms.evaluation.bench import find_skymaps
from mushrooms.tool.config import Config
from mushrooms.evaluation.gwemopt_baseline import _cache_read, cache_key, run_gwemopt
from mushrooms.scheduler_core.plan.document import parse_time
from mushrooms.scheduler_core.sky.skymap import read_skymap


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("skymap_dir")
    ap.add_argument("cache_dir")
    ap.add_argument("--config")
    ap.add_argument("--start")
    ap.add_argument("--timeout", type=float, default=1800.0)
    args = ap.parse_args()
    iers.conf.auto_download = False
    if args.config:
        data = tomllib.loads(Path(args.config).read_text())
        data.pop("bench", None)
        cfg = Config.from_mapping(data, source=args.config).scheduler
    else:
        cfg = Config().scheduler
    cache = Path(args.cache_dir)
    for path in find_skymaps(args.skymap_dir):
        skymap = read_skymap(path, nside=cfg.nside)
        if args.start:
            start = parse_time(args.start)
        elif skymap.event_time is not None:
            start = Time(skymap.event_time, scale="utc")
        else:
            print(f"{path.name}: no event time, skipped", flush=True)
            continue
        key = cache_key(path, start, cfg)
        if _cache_read(cache, key) is not None:
            print(f"{path.name}: cached {key[:12]}", flush=True)
            continue
        t0 = time.perf_counter()
        run = run_gwemopt(path, start, cfg, timeout_s=args.timeout, cache_dir=cache)
        print(f"{path.name}: {run.status} {len(run.observations)} exposures {time.perf_counter() - t0:.0f} s "
              f"{key[:12]} {run.message}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
