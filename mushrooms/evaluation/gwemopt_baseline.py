"""The real gwemopt as an optional baseline, run offline in its own interpreter.

gwemopt (``pip install gwemopt``, GPL-3.0) pins other versions of numpy,
astropy and ligo.skymap than ours, so it lives in a separate environment and
runs in a subprocess: the interpreter comes from ``$MUSHROOMS_GWEMOPT_PYTHON``
(or the caller).  Without it the baseline reports status ``unavailable``.

What is run: gwemopt 0.4.2's own command line (``gwemopt.run.run``), telescope
``ZTF`` (its bundled ``ZTF.config``, tessellation ``ZTF.tess`` = the 1778 ZTF
grid fields), MOC tiles, ``--doSchedule --scheduleType greedy`` (power-law
time allocation), the horizon ``--gpstime <start> --Tobs 0,<horizon days>``,
and the options of the row's named configuration
(:mod:`~mushrooms.evaluation.gwemopt_options`: ``gwemopt`` as the first
release ran it, ``gwemopt-o4`` as skyportal#4206's command line,
``gwemopt-skyportal`` as SkyPortal's plan form sends it; that module says
what every option does, with gwemopt's and SkyPortal's file:line).
Astropy's IERS auto-download is turned off before gwemopt is imported, so
nothing touches the network; our launcher also takes the fields gwemopt may
tile (``--mushrooms-fields``, SkyPortal's field selection), keeping only
those in the tiles gwemopt builds.

Its output ``schedule_ZTF.dat`` (``field ra dec tobs[MJD, exposure start]
limmag texp[s] prob airmass filter``) becomes our :class:`~mushrooms.scheduler_core.plan.document.Plan`;
gwemopt merges consecutive slots of one field and filter into one longer
exposure, which is kept as such (``exposure_s`` may be a multiple of ~310 s).
gwemopt's own efficiency code is never used.

Cache of raw schedules (``cache_dir``): gwemopt takes ~90 s per map, so its
raw output can be kept on disk and reused by later benchmarks.  One entry is
two files named by :func:`cache_key` (sha256 of the sky map file's bytes and
of the gwemopt options other than the input and output paths, i.e. horizon
start, horizon length and every option of the named configuration, the
field list included; the first release's row keeps its keys): ``<key>.dat`` is gwemopt's ``schedule_ZTF.dat`` verbatim and
``<key>.json`` holds ``{"skymap", "skymap_sha256", "args", "runtime_s",
"status", "message", "created"}``.  Only successful runs are cached; an
entry is written atomically (temporary name, then rename), so concurrent
benchmarks may share one directory.

Threads: gwemopt's libraries each start their own pools (OpenMP in
ligo.skymap and numpy's BLAS, rayon in mocpy, numba), sized to the machine.
Beside a study's other workers that oversubscribes the cores, so each pool is
capped at one thread (:data:`THREAD_CAPS`) unless the caller's environment
already sets it. The cap does not stop the churn: gwemopt's chip-gap
footprints call mocpy once per field, and mocpy's rayon pools come and go
with the calls, so on a starved machine thousands of exiting threads pile up
(one run was seen holding 4339). Under a limit of 600 processes (a cgroup's
``pids.max``) 18 of 40 runs failed with ``OSError: Resource temporarily
unavailable (os error 11)``; give gwemopt a limit of several thousand.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from astropy.time import Time, TimeDelta

from ..scheduler_core.config import PlanningConfig
from ..scheduler_core.plan.document import Observation, Plan, PlanMetrics, iso_utc, make_plan_id, sorted_observations
from .gwemopt_options import FIELDS_OPTION, GWEMOPT_CONFIGS, LEGACY, GwemoptConfig, gwemopt_args, portable_args

__all__ = ["GwemoptRun", "gwemopt_python", "run_gwemopt", "parse_schedule", "gwemopt_plan", "cache_key", "Repair",
           "repair_observations", "gwemopt_env", "THREAD_CAPS",
           "ENV_PYTHON"]

#: Environment variable naming the interpreter of a gwemopt installation.
ENV_PYTHON = "MUSHROOMS_GWEMOPT_PYTHON"

#: Thread-pool sizes given to gwemopt's process where the environment sets none.
THREAD_CAPS = {name: "1" for name in (
    "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS", "RAYON_NUM_THREADS")}


def gwemopt_env(base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment gwemopt runs in: ``base`` (default ``os.environ``), Agg plots, no warnings, thread caps.

    A thread cap already in ``base`` is kept (the caller chose it).
    """
    env = dict(os.environ if base is None else base)
    for name, value in THREAD_CAPS.items():
        env.setdefault(name, value)
    env.update(MPLBACKEND="Agg", PYTHONWARNINGS="ignore")
    return env


#: Runs gwemopt's CLI offline (our own lines, executed by gwemopt's interpreter). With ``--mushrooms-fields
#: 1,2,...`` (taken out of the line) only those fields keep their tiles, as SkyPortal's field selection does
#: (``gwemopt.run`` calls ``gwemopt.moc.create_moc`` through the module, so the wrapper is what it calls).
_LAUNCHER = (
    "import sys\n"
    "from astropy.utils import iers\n"
    "iers.conf.auto_download = False\n"
    "iers.conf.auto_max_age = None\n"
    "argv = sys.argv[1:]\n"
    f"if {FIELDS_OPTION!r} in argv:\n"
    f"    k = argv.index({FIELDS_OPTION!r})\n"
    "    keep = {int(f) for f in argv[k + 1].split(',') if f}\n"
    "    del argv[k:k + 2]\n"
    "    import gwemopt.moc\n"
    "    made = gwemopt.moc.create_moc\n"
    "    def create_moc(params, *a, **kw):\n"
    "        return {t: {i: m for i, m in s.items() if int(i) in keep} for t, s in made(params, *a, **kw).items()}\n"
    "    gwemopt.moc.create_moc = create_moc\n"
    "from gwemopt.run import run\n"
    "run(argv)\n"
)


@dataclass(frozen=True)
class GwemoptRun:
    """Outcome of one gwemopt run.

    Attributes
    ----------
    status : str
        ``ok``, ``unavailable``, ``failed``, ``timeout`` or ``not_cached``.
    observations : tuple of Observation
        Converted schedule (times in s since the horizon start).
    runtime_s : float
        Wall time of the subprocess (s).
    message : str
        One line: why it failed, or the command's tail.
    """

    status: str
    observations: tuple[Observation, ...]
    runtime_s: float
    message: str = ""


def gwemopt_python(explicit: str | None = None) -> str | None:
    """The gwemopt interpreter: ``explicit``, else ``$MUSHROOMS_GWEMOPT_PYTHON``, else this one when
    gwemopt imports here (``pip install 'mushrooms[gwemopt]'``), else None."""
    path = explicit or os.environ.get(ENV_PYTHON)
    if path:
        return path if Path(path).exists() else None
    import importlib.util

    try:
        found = importlib.util.find_spec("gwemopt") is not None
    except (ImportError, ValueError):
        found = False
    return sys.executable if found else None


def cache_key(skymap_path: str | Path, start: Time, config: PlanningConfig,
              named: GwemoptConfig = GWEMOPT_CONFIGS[LEGACY], fields: list[int] | None = None) -> str:
    """Cache key of one gwemopt run: sha256 of the map bytes and of its portable options (hex, 64 chars):
    every option of the named configuration and the field list are in it."""
    h = hashlib.sha256()
    h.update(hashlib.sha256(Path(skymap_path).read_bytes()).hexdigest().encode())
    h.update(json.dumps(portable_args(gwemopt_args(skymap_path, start, config, "out", named, fields))).encode())
    return h.hexdigest()


def _cache_read(cache_dir: Path, key: str) -> tuple[str, dict] | None:
    dat, meta = cache_dir / f"{key}.dat", cache_dir / f"{key}.json"
    try:
        return dat.read_text(), json.loads(meta.read_text())
    except (OSError, ValueError):
        return None


def _cache_write(cache_dir: Path, key: str, text: str, meta: dict) -> None:
    cache_dir.mkdir(parents=True, exist_ok=True)
    for suffix, body in ((".dat", text), (".json", json.dumps(meta, indent=1, sort_keys=True))):
        tmp = cache_dir / f".{key}{suffix}.{os.getpid()}.tmp"
        tmp.write_text(body)
        os.replace(tmp, cache_dir / f"{key}{suffix}")


#: gwemopt's ZTF.config ``overhead_per_exposure`` (s): its time slots are exposure + this.
GWEMOPT_ZTF_OVERHEAD_S = 10.0


def _snap_exposure(texp: np.ndarray, exposure_s: float, overhead_s: float) -> np.ndarray:
    """Undo gwemopt's ``%d`` truncation of exposure times (299.99999 is written 299).

    A merged run of k slots lasts ``k (exposure + overhead) - overhead``; a
    written value at most 1 s below such a length is snapped to it.
    """
    slot = exposure_s + overhead_s
    k = np.maximum(1, np.round((texp + overhead_s) / slot))
    cand = k * slot - overhead_s
    return np.where((cand - texp >= 0) & (cand - texp <= 1.0), cand, texp)


def parse_schedule(text: str, start: Time, exposure_s: float | None = None,
                   overhead_s: float = GWEMOPT_ZTF_OVERHEAD_S) -> tuple[Observation, ...]:
    """Read gwemopt's ``schedule_<telescope>.dat`` into observations.

    Parameters
    ----------
    text : str
        File contents: ``field ra dec tobs limmag texp prob airmass filter``
        per line, ``tobs`` the exposure start (MJD, UTC), ``texp`` in s
        (written truncated to an integer).
    start : astropy.time.Time
        Horizon start; observation times become seconds since it.
    exposure_s : float, optional
        The requested exposure time (s); when given, truncated exposure
        times are snapped back to whole slots (see :func:`_snap_exposure`).
    overhead_s : float
        gwemopt's overhead per exposure (s) for that snapping.

    Returns
    -------
    tuple of Observation
        In time order; ``block`` numbers runs of one filter.
    """
    rows = [ln.split() for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    if not rows:
        return ()
    fid = np.array([int(float(r[0])) for r in rows], dtype=np.int64)
    ra = np.array([float(r[1]) for r in rows])
    dec = np.array([float(r[2]) for r in rows])
    mjd = np.array([float(r[3]) for r in rows])
    texp = np.array([float(r[5]) for r in rows])
    if exposure_s is not None:
        texp = _snap_exposure(texp, float(exposure_s), overhead_s)
    filt = [r[8] for r in rows]
    t = (mjd - Time(start, scale="utc").mjd) * 86400.0
    order = np.argsort(t, kind="stable")
    obs = []
    block, prev = -1, None
    for k in order.tolist():
        if filt[k] != prev:
            block, prev = block + 1, filt[k]
        obs.append(Observation(int(fid[k]), float(ra[k]), float(dec[k]), filt[k],
                               float(round(t[k], 3)), float(texp[k]), block))
    return sorted_observations(obs)


def run_gwemopt(
    skymap_path: str | Path,
    start: Time,
    config: PlanningConfig,
    python: str | None = None,
    timeout_s: float = 1800.0,
    workdir: str | Path | None = None,
    cache_dir: str | Path | None = None,
    cache_only: bool = False,
    named: GwemoptConfig = GWEMOPT_CONFIGS[LEGACY],
    fields: list[int] | None = None,
) -> GwemoptRun:
    """Run gwemopt offline on one sky map.

    Parameters
    ----------
    skymap_path : str or pathlib.Path
        Sky map FITS file (gwemopt reads it itself).
    start : astropy.time.Time
        Horizon start (UTC).
    config : PlanningConfig
        The horizon, and the filters, exposure time, nside and airmass the
        named configuration leaves to it.
    python : str, optional
        gwemopt's interpreter (default: :func:`gwemopt_python`).
    timeout_s : float
        Kill gwemopt after this many seconds.
    workdir : str or pathlib.Path, optional
        Where gwemopt writes (default: a temporary directory, removed).
    cache_dir : str or pathlib.Path, optional
        Directory of cached raw schedules (see the module notes): a hit is
        returned without running gwemopt (``runtime_s`` is that of the
        original run), a successful run is stored.
    cache_only : bool
        With ``cache_dir``: never run gwemopt; a miss is status ``not_cached``.
    named : GwemoptConfig
        The row's named configuration (default: the first release's ``gwemopt``).
    fields : list of int, optional
        The fields gwemopt may tile (SkyPortal's field selection); None: all.

    Returns
    -------
    GwemoptRun
    """
    # absolute: gwemopt runs in its own directory, and takes a name it cannot open for a GraceDB event to download
    skymap_path = Path(skymap_path).resolve()
    key = None
    if cache_dir is not None:
        cache_dir = Path(cache_dir)
        key = cache_key(skymap_path, start, config, named, fields)
        hit = _cache_read(cache_dir, key)
        if hit is not None:
            text, meta = hit
            return GwemoptRun("ok", parse_schedule(text, start, named.exposure_of(config)),
                              float(meta.get("runtime_s", 0.0)), "cached")
        if cache_only:
            return GwemoptRun("not_cached", (), 0.0, f"not in the gwemopt cache {cache_dir}")
    exe = gwemopt_python(python)
    if exe is None:
        return GwemoptRun("unavailable", (), 0.0, f"no gwemopt interpreter (pip install 'mushrooms[gwemopt]', or set ${ENV_PYTHON})")
    with tempfile.TemporaryDirectory(prefix="gwemopt-") as tmp:
        out = Path(workdir) if workdir is not None else Path(tmp) / "out"
        args = gwemopt_args(skymap_path, start, config, out, named, fields)
        cmd = [exe, "-c", _LAUNCHER, *args]
        env = gwemopt_env()
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, env=env,
                                  cwd=tmp, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            return GwemoptRun("timeout", (), time.perf_counter() - t0, f"gwemopt exceeded {timeout_s:g} s")
        runtime = time.perf_counter() - t0
        sched = out / "schedule_ZTF.dat"
        if proc.returncode != 0 or not sched.exists():
            tail = (proc.stderr or proc.stdout or "").strip().splitlines()
            why = tail[-1] if tail else f"exit status {proc.returncode}"
            return GwemoptRun("failed", (), runtime, f"gwemopt exit {proc.returncode}: {why}"[:300])
        text = sched.read_text()
        obs = parse_schedule(text, start, named.exposure_of(config))
        if cache_dir is not None and key is not None:
            _cache_write(cache_dir, key, text, {
                "skymap": Path(skymap_path).name,
                "skymap_sha256": hashlib.sha256(Path(skymap_path).read_bytes()).hexdigest(),
                "configuration": named.name, "args": portable_args(args), "runtime_s": round(runtime, 3), "status": "ok", "message": "",
                "created": Time.now().isot + "Z"})
    return GwemoptRun("ok", obs, runtime, "")


def gwemopt_plan(run: GwemoptRun, start: Time, config: PlanningConfig, skymap_sha256: str,
                 coverage: float, name: str = LEGACY) -> Plan:
    """Wrap a gwemopt schedule as our :class:`~mushrooms.scheduler_core.plan.document.Plan` (for the checker).

    Parameters
    ----------
    run : GwemoptRun
        A successful run.
    start : astropy.time.Time
        Horizon start.
    config : PlanningConfig
        Gives the horizon.
    skymap_sha256 : str
        Sky map hash (for the plan id).
    coverage : float
        Probability covered (computed by the caller on our footprints).
    name : str
        The row (``metrics.solver``, and part of the plan id).
    """
    ids = {o.field_id for o in run.observations}
    metrics = PlanMetrics(coverage=round(float(coverage), 6), solver=name, status=run.status,
                          mip_gap=None, runtime_s=round(run.runtime_s, 3), n_fields=len(ids),
                          n_exposures=len(run.observations))
    return Plan(
        plan_id=make_plan_id(skymap_sha256, iso_utc(start), name, sys.version_info[:2]),
        start=Time(start, scale="utc"),
        end=Time(start, scale="utc") + TimeDelta(config.horizon_s, format="sec"),
        observations=run.observations,
        metrics=metrics,
    )


@dataclass(frozen=True)
class Repair:
    """What :func:`repair_observations` removed or moved.

    Attributes
    ----------
    observations : tuple of Observation
        The repaired schedule, in time order.
    counts : dict
        Exposures dropped per reason (``filter``, ``field``, ``horizon``,
        ``overlap``, ``window``, ``unpaired``) and ``delayed`` (exposures
        moved later by at most one overhead to respect the slew time).
    """

    observations: tuple[Observation, ...]
    counts: dict


def repair_observations(observations, problem) -> Repair:
    """A baseline's schedule with every exposure that breaks a rule removed.

    Rules, in this order (the plan checker's, on the problem's windows):

    1. ``filter``: only the configured filters;
    2. ``field``: only candidate fields of the problem (fields without
       probability or outside the declination band add nothing);
    3. ``horizon``: inside the planning horizon;
    4. ``window``: the whole exposure inside one window of its field
       (Sun, airmass, hour angle and mount keep-out limits, Moon);
    5. ``overlap``: in time order, an exposure starting before the previous
       kept one ends is dropped; one that starts after it but too soon for
       the slew/readout/filter change is delayed to the earliest allowed
       start (``delayed``) and dropped if that leaves its window;
    6. ``unpaired``: per field, one exposure in each filter the cadence
       apart is kept (the earliest such pair), with any other exposure that
       stays the cadence away from every kept one of the other filter; a
       field without such a pair loses all its exposures.

    Removing exposures only lengthens the gaps between the others, so the
    result passes the same rules again.

    Parameters
    ----------
    observations : sequence of Observation
        The schedule (times in s since the horizon start).
    problem : PlanningProblem
        Windows, candidate fields and configuration.

    Returns
    -------
    Repair
    """
    from ..scheduler_core.telescope.slew import overhead_time

    cfg = problem.config
    counts = {k: 0 for k in ("filter", "field", "horizon", "window", "overlap", "unpaired", "delayed")}
    w = problem.windows
    candidates = set(int(f) for f in problem.field_ids)

    def in_window(o: Observation, t: float) -> bool:
        return w.contains(o.field_id, t, t + o.exposure_s)

    kept = []
    for o in sorted(observations, key=lambda ob: ob.start):
        if o.filter not in cfg.filters:
            counts["filter"] += 1
        elif o.field_id not in candidates:
            counts["field"] += 1
        elif o.start < 0 or o.end > problem.horizon_s:
            counts["horizon"] += 1
        elif not in_window(o, o.start):
            counts["window"] += 1
        else:
            kept.append(o)
    timed: list[Observation] = []
    for o in kept:
        if timed:
            p = timed[-1]
            if o.start < p.end:
                counts["overlap"] += 1
                continue
            need = float(overhead_time(p.ra, p.dec, o.ra, o.dec, cfg.slew,
                                       cfg.filter_change_s if p.filter != o.filter else 0.0))
            if o.start < p.end + need:
                t = p.end + need
                if not in_window(o, t) or t + o.exposure_s > problem.horizon_s:
                    counts["overlap"] += 1
                    continue
                o = Observation(o.field_id, o.ra, o.dec, o.filter, float(t), o.exposure_s, o.block)
                counts["delayed"] += 1
        timed.append(o)
    if len(cfg.filters) < 2:
        raise ValueError(f"the gwemopt baseline's repair keeps pairs: filters {list(cfg.filters)!r} has one filter")
    f1, f2 = cfg.filters[:2]  # a sequence (g-r-g): pairs of its first two, later visits kept a cadence apart
    by_field: dict[int, list[Observation]] = {}
    for o in timed:
        by_field.setdefault(o.field_id, []).append(o)
    final: list[Observation] = []
    for fid, obs in by_field.items():
        a = [o for o in obs if o.filter == f1]
        b = [o for o in obs if o.filter == f2]
        pairs = [(max(x.start, y.start), x, y) for x in a for y in b if abs(x.start - y.start) >= cfg.cadence_s - 1e-3]
        if not pairs:
            counts["unpaired"] += len(obs)
            continue
        _, x, y = min(pairs, key=lambda p: p[0])
        keep = [x, y]
        for o in sorted(obs, key=lambda ob: ob.start):
            if o is x or o is y:
                continue
            other = [k for k in keep if k.filter != o.filter]
            if all(abs(o.start - k.start) >= cfg.cadence_s - 1e-3 for k in other):
                keep.append(o)
            else:
                counts["unpaired"] += 1
        final += keep
    return Repair(sorted_observations(final), counts)
