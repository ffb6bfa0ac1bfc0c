"""Independent plan checker: is a plan something ZTF can really execute?

The checker shares no code with the schedulers' geometry (``fields``,
``visibility``, ``slew``), so a bug there cannot hide behind the same bug
here: its field grid, footprints, site, mount and slew arithmetic and its
Sun and Moon are its own (:mod:`.check_geometry`); this module holds the
rules a plan is checked against and the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from astropy import units as u
from astropy.time import Time

from ..config import PlanningConfig
from ..executed import MIN_PROCESSED_FRACTION, ExecutedExposure, done_pairs, is_done
from .check_geometry import P48_SITE, altaz_slew_seconds, conditions, field_positions, mount_reachable, \
    polygon_coverage, slew_seconds
from .check_telescope import check_scope
from .document import Plan
from .sequence_check import check_sequences, covered_by_record
from ..sky.skymap import SkyMap

__all__ = ["CheckReport", "check_plan", "exposures_in_windows", "polygon_coverage", "mount_reachable",
           "slew_seconds", "P48_SITE"]

#: Slack allowed against each constraint (numerical noise only).
TOL_TIME_S = 1e-3
TOL_AIRMASS = 0.01
TOL_SUN_DEG = 0.05
TOL_MOON_DEG = 0.1
TOL_HA_H = 0.005
#: Reported and recomputed coverage may differ by this much (absolute):
#: the two footprint methods differ only at pixel centres on CCD edges.
TOL_COVERAGE = 2e-3
#: Field centres in the plan may differ from the grid's by this much (deg).
TOL_POSITION_DEG = 1e-3
MAX_LISTED = 20


@dataclass(frozen=True)
class CheckReport:
    """Verdict of the plan checker.

    Attributes
    ----------
    ok : bool
        True when no problem was found.
    problems : tuple of str
        One line per problem (the first MAX_LISTED of each kind), each
        starting with its kind (``window:``, ``slew:``, ...).
    coverage : float
        Probability recomputed from the planned fields' CCD outlines.
    reported_coverage : float or None
        The plan's own ``metrics.coverage``.
    counts : dict of str to int
        Number of problems of each kind (all of them, not only those listed).
    """

    ok: bool
    problems: tuple[str, ...]
    coverage: float
    reported_coverage: float | None = None
    counts: dict[str, int] = field(default_factory=dict)


# --------------------------------------------------------------------------- the check

class _Problems:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.counts: dict[str, int] = {}

    def add(self, kind: str, text: str) -> None:
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if self.counts[kind] <= MAX_LISTED:
            self.lines.append(f"{kind}: {text}")


def check_plan(plan: Plan, skymap: SkyMap, config: PlanningConfig = PlanningConfig(),
               coverage_tolerance: float = TOL_COVERAGE, *, executed: Sequence[ExecutedExposure] = (),
               min_processed_fraction: float = MIN_PROCESSED_FRACTION) -> CheckReport:
    """Verify a plan against the telescope, the sky and the cadence rule.

    Checks: known fields with the grid's coordinates; allowed filters;
    exposures in time order, not overlapping, separated by at least the
    slew/readout/filter-change overhead; inside the horizon; every
    exposure (start, middle, end) with the Sun low enough, airmass,
    hour angle and mount limits, Moon separation; every field observed in
    both filters at least the cadence apart; reported coverage equal to the
    recomputed one.

    With an executed record (a re-plan, ``docs/design/replan.md``): no
    exposure of a field done in both filters (E3); a field's done exposures
    (E1) count towards its pair, which then needs its two filters the
    cadence apart at their widest (E3), so a half-done field may get its
    other filter only; the coverage is recomputed outside the executed
    pairs (P8) and ``metrics.coverage_executed`` compared with theirs.

    Parameters
    ----------
    plan : Plan
        The plan.
    skymap : SkyMap
        The sky map it was made for (for coverage).
    config : PlanningConfig
        Constraints to check against.
    coverage_tolerance : float
        Largest allowed |reported - recomputed| coverage.
    executed : sequence of ExecutedExposure
        What the telescope did before the plan (default none).
    min_processed_fraction : float
        The done rule (E1) for ``executed``.

    Returns
    -------
    CheckReport

    Examples
    --------
    >>> from importlib.resources import files
    >>> from astropy.time import Time
    >>> from mushrooms.scheduler_core import PlanningConfig, read_skymap
    >>> path = files("mushrooms.scheduler_core") / "data" / "MS181101ab_bayestar.multiorder.fits"
    >>> config = PlanningConfig(solver="greedy", nside=64)
    >>> skymap = read_skymap(path, nside=config.nside)
    >>> night = Time("2019-05-01T03:00:00", scale="utc")
    >>> from mushrooms.scheduler_core import make_plan
    >>> plan = make_plan(skymap, config, start=night)  # checked on the way out too
    >>> report = check_plan(plan, skymap, config)
    >>> report.ok, report.problems
    (True, ())
    >>> abs(report.coverage - plan.metrics.coverage) < 1e-4
    True

    A plan that breaks the cadence rule (its second pass moved onto the
    first) is refused, with one line per problem:

    >>> import dataclasses
    >>> early = tuple(dataclasses.replace(o, start=o.start - config.cadence_s) if o.filter == "r" else o
    ...               for o in plan.observations)
    >>> bad = check_plan(dataclasses.replace(plan, observations=early), skymap, config)
    >>> bad.ok, len(bad.problems) > 0
    (False, True)
    """
    p = _Problems()
    obs = plan.observations
    horizon = float((plan.end - plan.start).to_value(u.s))
    if config.revisit and executed:  # (N4, N5) revisit: only the plan's own night's exposures count as done
        from ..executed import counted_for_night
        from ..sky.twilight import night_evening

        executed = counted_for_night(executed, night_evening(plan.start, config), True)
    done = _done_times(executed, plan.start, min_processed_fraction)
    coverage, reported = _check_coverage(p, plan, skymap, config, coverage_tolerance, _covered(
        executed, done, config, min_processed_fraction))
    if not obs:
        return CheckReport(not p.lines, tuple(p.lines), coverage, reported, p.counts)

    cap = config.max_open_shutter_s
    open_s = sum(float(o.exposure_s) for o in obs)
    if cap is not None and open_s > cap + 1e-6:  # (S4) the open-shutter budget
        p.add("open shutter", f"{open_s:.0f} s of exposures pass max_open_shutter_s = {cap:g} s")
    x = _Exposures.of(obs)
    _check_fields(p, x, config)
    _check_sequence(p, x, horizon, config, plan.start)
    _check_conditions(p, x, plan.start, config)
    if len(config.filters) == 2:
        _check_cadence(p, x, config, done)
    else:  # (F6-F8) a sequence of another length: its own rules, sequence_check.py
        check_sequences(p.add, x.ids, x.flt, x.start, tuple(config.filters), config.cadence_s,
                        config.pair_separation_s, done, _next_visit_clear(x, plan.start, config, horizon))

    return CheckReport(not p.lines, tuple(p.lines), coverage, reported, p.counts)


def _check_coverage(p: _Problems, plan: Plan, skymap: SkyMap, config: PlanningConfig, coverage_tolerance: float,
                    covered: set[int]) -> tuple[float, float | None]:
    """Reported coverage against the footprints (outside the executed pairs, P8), the bound (B3), repeats (P9).

    Returns (recomputed coverage, reported coverage or None).
    """
    obs = plan.observations
    scope = check_scope(config)
    coverage = polygon_coverage((o.field_id for o in obs), skymap.prob, without=covered, scope=scope)
    reported = plan.metrics.coverage if plan.metrics is not None else None
    if reported is not None and abs(float(reported) - coverage) > coverage_tolerance:
        p.add("coverage", f"reported {reported:.5f} but the footprints hold {coverage:.5f}")
    bound = None if plan.metrics is None else plan.metrics.upper_bound
    if reported is not None and bound is not None and float(reported) > float(bound):
        # (B3) the certified bound (its margin included, milp.md B1, B2) is above every plan's coverage
        p.add("bound", f"reported coverage {reported:.7f} above the certified upper bound {bound:.7f}")
    reported_executed = None if plan.metrics is None else plan.metrics.coverage_executed
    if reported_executed is not None:
        held = polygon_coverage(covered, skymap.prob, scope=scope)
        if abs(float(reported_executed) - held) > coverage_tolerance:
            p.add("coverage", f"reported {reported_executed:.5f} executed but the executed pairs hold {held:.5f}")
    # (P9) with an executed record: no exposure of a field done in both filters (a sequence: F7, F8)
    for fid in sorted({o.field_id for o in obs} & set(covered) if len(config.filters) == 2 else ()):
        p.add("repeat", f"field {fid} is done in both {config.filters[0]} and {config.filters[1]} "
                        f"(executed) and planned again")
    return coverage, reported


@dataclass(frozen=True)
class _Exposures:
    """A plan's exposures as arrays, in plan order."""

    ids: np.ndarray
    ra: np.ndarray
    dec: np.ndarray
    flt: np.ndarray
    start: np.ndarray
    exp: np.ndarray

    @property
    def end(self) -> np.ndarray:
        return self.start + self.exp

    @classmethod
    def of(cls, obs) -> "_Exposures":
        return cls(np.array([o.field_id for o in obs]), np.array([o.ra for o in obs], float),
                   np.array([o.dec for o in obs], float), np.array([o.filter for o in obs]),
                   np.array([o.start for o in obs], float), np.array([o.exposure_s for o in obs], float))


def _check_fields(p: _Problems, x: _Exposures, config: PlanningConfig) -> None:
    """Known fields where the grid puts them, allowed filters, positive exposures."""
    scope = check_scope(config)
    grid = field_positions() if scope is None else scope.positions
    ids, ra, dec, flt, exp = x.ids, x.ra, x.dec, x.flt, x.exp
    known = np.array([int(f) in grid for f in ids])
    for i in np.flatnonzero(~known):
        p.add("field", f"unknown field {ids[i]}")
    where = np.array([grid.get(int(f), (np.nan, np.nan)) for f in ids], float)
    d_ra = np.abs((where[:, 0] - ra + 180.0) % 360.0 - 180.0)
    off = known & ((d_ra > TOL_POSITION_DEG) | (np.abs(where[:, 1] - dec) > TOL_POSITION_DEG))
    for i in np.flatnonzero(off):
        p.add("field", f"field {ids[i]} at ({ra[i]:.4f}, {dec[i]:.4f}) is not where the grid puts it")
    for i in np.flatnonzero(~np.isin(flt, config.filters)):
        p.add("filter", f"field {ids[i]} in filter {flt[i]!r}, not one of {config.filters}")
    for i in np.flatnonzero(exp <= 0):
        p.add("exposure", f"field {ids[i]} has exposure {exp[i]} s")


def _check_sequence(p: _Problems, x: _Exposures, horizon: float, config: PlanningConfig, t0: Time) -> None:
    """Order, overlaps and overheads (readout, slew and filter change run in parallel); the horizon.

    (M1) An alt-azimuth mount's slew is timed on its axes at the end of the exposure before it.
    """
    ids, ra, dec, flt, start, end = x.ids, x.ra, x.dec, x.flt, x.start, x.end
    for i in np.flatnonzero(np.diff(start) < 0):
        p.add("order", f"exposure {i + 1} (field {ids[i + 1]}) starts before exposure {i}")
    gap = start[1:] - end[:-1]
    scope = check_scope(config)
    slews = (altaz_slew_seconds(ra[:-1], dec[:-1], ra[1:], dec[1:], end[:-1], t0, scope.site, config.slew)
             if scope is not None and scope.altaz else slew_seconds(ra[:-1], dec[:-1], ra[1:], dec[1:], config.slew))
    need = np.maximum.reduce([
        slews,
        np.full(gap.size, config.slew.readout_s),
        np.where(flt[:-1] != flt[1:], config.filter_change_s, 0.0),
    ])
    for i in np.flatnonzero(gap < 0):
        p.add("overlap", f"field {ids[i + 1]} {flt[i + 1]} starts {-gap[i]:.1f} s before field {ids[i]} {flt[i]} ends")
    for i in np.flatnonzero((gap >= 0) & (gap < need - TOL_TIME_S)):
        p.add("slew", f"only {gap[i]:.1f} s from field {ids[i]} {flt[i]} to field {ids[i + 1]} {flt[i + 1]}, needs {need[i]:.1f} s")

    for i in np.flatnonzero((start < -TOL_TIME_S) | (end > horizon + TOL_TIME_S)):
        p.add("horizon", f"field {ids[i]} {flt[i]} at {start[i]:.0f}-{end[i]:.0f} s is outside the horizon 0-{horizon:.0f} s")


@dataclass(frozen=True)
class _Windows:
    """Observing conditions at start, middle and end of each exposure ((3, n) arrays) and which rule each breaks."""

    sun_alt: np.ndarray
    airmass: np.ndarray
    ha: np.ndarray
    moon_sep: np.ndarray
    sun_bad: np.ndarray
    airmass_bad: np.ndarray
    mount_bad: np.ndarray
    moon_bad: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        """(n,) True where the whole exposure is inside its field's window."""
        return ~(self.sun_bad | self.airmass_bad | self.mount_bad | self.moon_bad)


def _windows(x: _Exposures, t0: Time, config: PlanningConfig, strict: bool = False) -> _Windows:
    """The window rules (Sun, airmass, mount, Moon) at start, middle and end of every exposure.

    Each rule may be missed by its tolerance (the planner's model of the sky
    is not the checker's); ``strict``: each must hold by its tolerance
    instead (an exposure the planner's model would also find inside).
    """
    ra, dec, start, exp = x.ra, x.dec, x.start, x.exp
    n = len(ra)
    scope = check_scope(config)
    c = conditions(t0, np.concatenate([start, start + exp / 2, x.end]), np.tile(ra, 3), np.tile(dec, 3),
                   P48_SITE if scope is None else scope.site)
    sun_alt, airmass, ha, moon_sep = (a.reshape(3, n) for a in (c.sun_alt, c.airmass, c.ha, c.moon_sep))
    slack = TOL_HA_H * 15.0  # each HA limit may be missed by this much (deg)
    reach = mount_reachable if scope is None else scope.reachable
    both = np.logical_and if strict else np.logical_or
    mount_ok = both(both(reach(ha, dec[None, :], config.ha_max_h), reach(ha - slack, dec[None, :], config.ha_max_h)),
                    reach(ha + slack, dec[None, :], config.ha_max_h))
    sign = -1.0 if strict else 1.0
    return _Windows(sun_alt, airmass, ha, moon_sep,
                    sun_bad=(sun_alt > config.sun_alt_max_deg + sign * TOL_SUN_DEG).any(axis=0),
                    airmass_bad=(airmass > config.airmass_max + sign * TOL_AIRMASS).any(axis=0),
                    mount_bad=(~mount_ok).any(axis=0),
                    moon_bad=(moon_sep < config.moon_sep_min_deg - sign * TOL_MOON_DEG).any(axis=0))


def _next_visit_clear(x: _Exposures, t0: Time, config: PlanningConfig, horizon: float):
    """(F10) the checker's own answer to "could a cut sequence's next visit have been taken?".

    For each cut sequence, candidate starts every ``time_step_s`` from
    ``after`` to ``until`` (and the horizon less the exposure); a start is
    *clear* when the window rules hold, each by its tolerance (``strict``),
    over the exposure widened by one ``time_step_s`` on each side (start,
    middle and end), so a window the planner found on its grid of that step,
    to within a step and a tolerance of the checker's sky, would have held the
    exposure.  Returns the first clear start (s), NaN where none.
    """
    step = float(config.time_step_s)
    where = {int(f): i for i, f in enumerate(x.ids)}

    def clear(fields: np.ndarray, bands: np.ndarray, after: np.ndarray, until: np.ndarray) -> np.ndarray:
        idx, ts = [], []
        for n, (f, a, b) in enumerate(zip(fields, after, until)):
            i = where[int(f)]
            t = np.arange(a, min(b, horizon - x.exp[i]) + 1e-9, step)
            idx += [n] * t.size
            ts.append(t)
        out = np.full(len(fields), np.nan)
        if not idx:
            return out
        n_of = np.asarray(idx)
        rows = np.array([where[int(fields[n])] for n in n_of])
        t = np.concatenate(ts)
        trial = _Exposures(x.ids[rows], x.ra[rows], x.dec[rows], bands[n_of], t - step, x.exp[rows] + 2 * step)
        ok = _windows(trial, t0, config, strict=True).ok
        for n in np.unique(n_of[ok]):
            out[n] = t[ok & (n_of == n)][0]
        return out

    return clear


def exposures_in_windows(plan: Plan, config: PlanningConfig = PlanningConfig()) -> np.ndarray:
    """Which of a plan's exposures lie wholly inside their field's window (the checker's own Sun, airmass,
    hour-angle and mount, Moon rules at start, middle and end; its tolerances).

    Returns
    -------
    numpy.ndarray
        (n,) bool, in plan order (empty for a plan without exposures).
    """
    if not plan.observations:
        return np.zeros(0, dtype=bool)
    return _windows(_Exposures.of(plan.observations), plan.start, config).ok


def _check_conditions(p: _Problems, x: _Exposures, t0: Time, config: PlanningConfig) -> None:
    """Observing conditions at start, middle and end of each exposure ((3, n) arrays)."""
    ids, dec, flt, start = x.ids, x.dec, x.flt, x.start
    w = _windows(x, t0, config)
    for i in np.flatnonzero(w.sun_bad):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: Sun at {w.sun_alt[:, i].max():.1f} deg")
    for i in np.flatnonzero(w.airmass_bad):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: airmass {w.airmass[:, i].max():.2f}")
    for i in np.flatnonzero(w.mount_bad):
        worst = w.ha[np.argmax(np.abs(w.ha[:, i])), i]
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: hour angle {worst / 15:.2f} h "
                        f"(Dec {dec[i]:.1f}) beyond the mount limits")
    for i in np.flatnonzero(w.moon_bad):
        p.add("window", f"field {ids[i]} {flt[i]} at {start[i]:.0f} s: Moon {w.moon_sep[:, i].min():.1f} deg away")


def _covered(executed: Sequence[ExecutedExposure], done: dict[int, dict[str, np.ndarray]],
             config: PlanningConfig, min_processed_fraction: float) -> set[int]:
    """The fields the record covers: done in both filters (E3), for a sequence the first two (F7)."""
    if len(config.filters) == 2:
        return set(done_pairs(executed, tuple(config.filters), min_processed_fraction, config.cadence_s,
                              config.pair_separation_s).both)
    return set(covered_by_record(done, tuple(config.filters), config.cadence_s, config.pair_separation_s))


def _done_times(executed: Sequence[ExecutedExposure], t0: Time,
                min_processed_fraction: float) -> dict[int, dict[str, np.ndarray]]:
    """Field -> filter -> starts (s since ``t0``, negative before it) of the done executed exposures (E1)."""
    out: dict[int, dict[str, list[float]]] = {}
    for e in executed:
        if is_done(e, min_processed_fraction):
            out.setdefault(e.field_id, {}).setdefault(e.filter, []).append(float((e.start - t0).to_value(u.s)))
    return {f: {b: np.array(v) for b, v in per.items()} for f, per in out.items()}


def _check_cadence(p: _Problems, x: _Exposures, config: PlanningConfig,
                   done: dict[int, dict[str, np.ndarray]] | None = None) -> None:
    """Both filters per field, the cadence apart; a field with done exposures counts them (E3: widest separation)."""
    ids, flt, start = x.ids, x.flt, x.start
    f1, f2 = config.filters
    done = done or {}
    for fid in np.unique(ids):
        sel = ids == fid
        before = done.get(int(fid), {})
        t1 = np.concatenate([start[sel & (flt == f1)], before.get(f1, np.zeros(0))])
        t2 = np.concatenate([start[sel & (flt == f2)], before.get(f2, np.zeros(0))])
        if t1.size == 0 or t2.size == 0:
            p.add("cadence", f"field {fid} is not observed in both {f1} and {f2}")
            continue
        gaps = np.abs(t1[:, None] - t2[None, :])
        if before:  # (E3, P10) some a and b exposure the cadence apart, and within the largest separation
            paired = (gaps >= config.cadence_s - TOL_TIME_S) & (gaps <= config.pair_separation_s + TOL_TIME_S)
            if not paired.any():
                p.add("cadence", f"field {fid}: no {f1} and {f2} exposure {config.cadence_s:.0f} s to "
                                 f"{config.pair_separation_s:.0f} s apart (its executed ones included)")
            continue
        sep = gaps.min()
        if sep < config.cadence_s - TOL_TIME_S:
            p.add("cadence", f"field {fid}: {f1} and {f2} only {sep:.0f} s apart (cadence {config.cadence_s:.0f} s)")
