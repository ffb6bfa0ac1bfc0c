"""Fill the on-disk cache of raw gwemopt schedules for a directory of sky maps.

gwemopt takes ~90 s per map; ``mushrooms bench`` with ``[bench]
gwemopt_cache_dir`` then scores its plans (raw and repaired) without
running it again.  One map at a time, in this process's order; maps already
cached are skipped.  Horizon start = the map's event time (as the bench's
default) unless ``--start``; planning options from ``--config`` (default:
the built-in defaults), so the keys match a bench run with the same config.  ``--configs`` names the
gwemopt configurations to cache (``mushrooms/evaluation/gwemopt_options.py``: ``gwemopt``, the default, which
``gwemopt-repaired`` also reads; ``gwemopt-o4``; ``gwemopt-skyportal``, its fields chosen as the bench chooses them).

    MUSHROOMS_GWEMOPT_PYTHON=/path/to/python nice -n 10 \\
        .venv/bin/python benchmarks/science/gwemopt_cache.py ../shared/data/skymaps CACHE_DIR [--configs gwemopt,gwemopt-o4]
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
from mushrooms.evaluation.gwemopt_options import GWEMOPT_CONFIGS, credible_fields
from mushrooms.scheduler_core.plan.document import parse_time
from mushrooms.scheduler_core.sky.skymap import read_skymap


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("skymap_dir")
    ap.add_argument("cache_dir")
    ap.add_argument("--config")
    ap.add_argument("--start")
    ap.add_argument("--timeout", type=float, default=1800.0)
    ap.add_argument("--configs", default="gwemopt", help="comma-separated: " + ", ".join(GWEMOPT_CONFIGS))
    args = ap.parse_args()
    names = [c for c in args.configs.split(",") if c]
    if not names or any(c not in GWEMOPT_CONFIGS for c in names):
        print(f"--configs {args.configs!r}: choose from {', '.join(GWEMOPT_CONFIGS)}", file=sys.stderr)
        return 2
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
        for name in names:
            named = GWEMOPT_CONFIGS[name]
            fields = None
            if named.credible_fields is not None:
                from mushrooms.scheduler_core.sky.fields import field_footprints, load_ztf_fields

                fields = credible_fields(field_footprints(load_ztf_fields(), cfg.nside), skymap.prob,
                                         named.credible_fields)
            key = cache_key(path, start, cfg, named, fields)
            if _cache_read(cache, key) is not None:
                print(f"{path.name} {name}: cached {key[:12]}", flush=True)
                continue
            t0 = time.perf_counter()
            run = run_gwemopt(path, start, cfg, timeout_s=args.timeout, cache_dir=cache, named=named, fields=fields)
            print(f"{path.name} {name}: {run.status} {len(run.observations)} exposures "
                  f"{time.perf_counter() - t0:.0f} s {key[:12]} {run.message}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
