"""Planning parameters: one small frozen dataclass a notebook can build by hand.

Every default here is the documented default of the ``[scheduler]`` section
of ``config.toml``; a test keeps the two in step.  Imports only the standard
library and leaves (:mod:`.tables`, :mod:`.ranges`, the checks :mod:`.config_checks`), so
reading the configuration loads no numpy or astropy.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

from .config_checks import MAX_TIME_STEPS  # noqa: F401  (the checks' limit, still config's name)
from .config_checks import (MAX_SEQUENCE, ZTF_FILTERS, filter_sequence_problems, grid_problems, scheduler_problems,
                            stage_problems, telescope_problems)
from .instruments.names import DEFAULT_TELESCOPES
from .instruments.reference import ZTF_THRESHOLDS
from .ranges import require_finite, setting
from .solvers_registry import SOLVER_NAMES  # scheduler names (``milp`` = ``blocks``): the registry's
from .tables import dataclass_from_table

__all__ = ["PlanningConfig", "SlewModel", "ZTF_FILTERS", "SOLVER_NAMES", "RECORDED_WHEN_SET", "MAX_SEQUENCE",
           "filter_sequence_problems"]

@dataclass(frozen=True)
class SlewModel:
    """ZTF/P48 per-axis trapezoidal slew model (ztf_sim's drive parameters).

    Each axis accelerates at a constant rate up to a maximum speed, cruises,
    and decelerates at the same rate; the slew lasts as long as the slower
    axis, plus a settle time.  The CCD readout of the previous exposure runs
    during the slew, so the gap between two exposures is at least the
    readout time.

    Sources of the defaults: ztf_sim (``ZwickyTransientFacility/ztf_sim``,
    ``ztf_sim/constants.py`` at commit c5ab409, 2026-02): ``P48_slew_pars``
    (HA and Dec from the Telescope Drive Performance Assessment v1.2),
    ``SETTLE_TIME = 1 s`` and ``READOUT_TIME = 8 s``.  Other published values
    differ: gwemopt's ``ZTF.config`` has ``readout 10`` s, and older ztf_sim
    commits had 10 s readout and 2 s settle.

    Attributes
    ----------
    ha_accel_deg_s2, ha_vmax_deg_s : float
        Hour-angle axis acceleration (deg s^-2) and top speed (deg s^-1);
        ztf_sim: 0.4 and 2.5.
    dec_accel_deg_s2, dec_vmax_deg_s : float
        Declination axis acceleration (deg s^-2) and top speed (deg s^-1);
        ztf_sim: 0.5 and 3.0.
    settle_s : float
        Settle time after any non-zero slew (s); ztf_sim ``SETTLE_TIME``.
    readout_s : float
        CCD readout time (s); overlaps the slew; ztf_sim ``READOUT_TIME``.
    """

    ha_accel_deg_s2: float = setting(0.4, 0, 10, "deg s^-2", lo_open=True, why="a drive, not a jump")
    ha_vmax_deg_s: float = setting(2.5, 0, 20, "deg s^-1", lo_open=True, why="a drive, not a jump")
    dec_accel_deg_s2: float = setting(0.5, 0, 10, "deg s^-2", lo_open=True, why="a drive, not a jump")
    dec_vmax_deg_s: float = setting(3.0, 0, 20, "deg s^-1", lo_open=True, why="a drive, not a jump")
    settle_s: float = setting(1.0, 0, 60, "s")
    readout_s: float = setting(8.0, 0, 120, "s", why="ZTF reads out in 8 s")

    def __post_init__(self) -> None:
        require_finite(self, "scheduler.slew")


#: Keys a plan records only when set (non-empty, true): added after plan ids existed, they leave the
#: document and the plan id of a configuration without them as they were (:meth:`PlanningConfig.record`).
RECORDED_WHEN_SET = ("exposure_menu_s", "revisit", "bound_refine_ends", "pair_max_s", "hybrid_blocks",
                     "hybrid_paced_slots", "deterministic", "max_open_shutter_s")
#: Keys a plan records only when false (switches that are on by default and were always on before they existed).
RECORDED_WHEN_CLEARED = ("hybrid_lns",)
#: (P10) A pair's largest separation when ``pair_max_s = 0``: one night (12 h: longer than any night at
#: Palomar, shorter than the day to the next one).
ONE_NIGHT_PAIR_S = 43200.0


def _names_only(names: Any) -> Any:
    """An object with ``telescopes`` (what :func:`~.config_checks.telescope_problems` reads)."""
    from types import SimpleNamespace

    return SimpleNamespace(telescopes=names)


def _ztf_default(key: str, value: Any, cls: type | None = None) -> bool:
    """``value`` is ZTF's default of ``key`` (a ``PlanningConfig`` field, or ``cls``'s)."""
    fields = {f.name: f for f in dataclasses.fields(cls or PlanningConfig)}
    if key not in fields or fields[key].default is dataclasses.MISSING:
        return False
    default = fields[key].default
    return (tuple(value) == tuple(default)) if isinstance(default, tuple) and isinstance(value, (list, tuple)) \
        else value == default


@dataclass(frozen=True)
class PlanningConfig:
    """Everything that shapes a plan, in astronomer's units.

    Attributes
    ----------
    nside : int
        Working HEALPix resolution (NESTED ordering) for coverage.
    horizon_h : float
        Planning horizon (hours) from the start time.
    nights : int
        Nights planned, one plan document each over its own validity window
        (that night's twilights, :func:`~.nights.plan_nights`); 1 (the
        default): one plan over ``horizon_h`` from the start, as before.
    revisit : bool
        With ``nights > 1``: each later night is planned on the whole map
        again, re-observing earlier nights' fields for the light curve (as
        ZTF's GW programme did), counting only that night's own executed
        exposures as done (``docs/design/replan.md`` N4).  False (the
        default): a later night covers what is still uncovered (N3).
    pair_max_s : float
        (P10) Largest separation (s) of a pair's two filters counted with an
        executed record: a field done in one filter more than this before
        has no pending visit (it is planned as a new pair), and a done pair
        counts only within it.  0 (the default): one night, 12 h.
    time_step_s : float
        Step (s) of the time grid on which observability windows are found.
    sun_alt_max_deg : float
        Observing only while the Sun is below this altitude (deg).
    airmass_max : float
        Largest airmass (plane-parallel sec z) allowed.
    ha_max_h : float
        Largest |hour angle| (hours) the P48 mount reaches.
    moon_sep_min_deg : float
        Smallest Moon separation (deg) from a field centre.
    dec_min_deg, dec_max_deg : float
        Fields outside this declination band (deg) are never planned.
    exposure_s : float
        Exposure time per visit (s).
    filters : tuple of str
        The filter sequence each field is visited in, in order (F1-F4,
        ``docs/design/sequences.md``): ``("g", "r")`` (the default pair),
        ``("g", "r", "g")`` (ZTF's O4 GW sequence), any 1 to
        :data:`MAX_SEQUENCE` ZTF filters changing at every visit.  The first
        two make a field covered; later visits add no coverage.
    cadence_s : float
        Least time (s) between consecutive visits of one field.
    filter_change_s : float
        Filter exchange time (s).  The default 120 s is the MUSHROOMS
        paper's 2-minute filter exchange; ztf_sim's ``FILTER_CHANGE_TIME``
        is 135 s and gwemopt's ZTF config has 60 s.
    slew_estimate_s : float
        Mean slew+readout overhead (s) the block MILP assumes before the
        real order is known.
    n_fields : int or None
        Shortlist size after pruning; None sizes it from the horizon.
    max_open_shutter_s : float or None
        Open-shutter (telescope-time) budget (s): the plan's exposures sum
        to at most this (greedy stops before the field whose visits exceed
        it; the slot MILPs carry equation S4 of ``docs/design/milp.md``);
        None (default): no cap, the plans of before the key existed.
    n_blocks_max : int
        Most observing blocks in the MILP (b_max).
    min_block_size : int
        Least number of fields in a MILP block.  0 (default) applies the
        paper's rule, b_size = ceil((cadence - t_filt) / (t_exp + t_slew)),
        so that no block waits for the cadence; a positive number overrides
        it (1 lets short-lived fields into small blocks that wait for the
        cadence: more coverage on some maps, harder models).
    penalty : float
        Objective penalty per field-block assignment (p).
    block_gap_s : float
        Extra time (s) inserted between blocks (g_i) on a first solve.
    solver : str
        Default scheduler: ``greedy``, ``slots`` (slot-assignment MILP
        portfolio), ``blocks`` (the paper's block MILP; ``milp`` is an
        alias) or ``hybrid`` (best of greedy, slots, the LNS re-solves of
        the best plan and, when time is left, blocks).
    milp_backend : str
        ``auto`` (Gurobi if fully licensed, else HiGHS), ``highs`` or ``gurobi``.
    time_limit_s : float
        Budget (s; work s when ``deterministic``) of one plan: ``slots``
        shares it over its grids; ``blocks`` gives it to its first solve
        (a re-solve gets a third); ``hybrid`` gives it to the slot
        portfolio, the time left to the LNS re-solves (which stop early
        when a round of slices or 3 s bring nothing) and what is then
        left (if at least ``MIN_BLOCKS_S``; at most ``BLOCKS_LIMIT_S``, 1 s)
        to the block MILP when ``hybrid_blocks``.  With
        ``objective = "detection"`` it is the budget of the whole
        optimisation: the scheduler gets ``time_limit_s -
        detection_time_limit_s``, the detection stage the rest.
        Default 14 s = 10 s for the scheduler + 4 s detection share.
        Preparation, greedy, the upper bound and the checker
        come on top (about 2-4 s; imports about 3 s more for the CLI).
    mip_gap : float
        Relative optimality gap at which the solver may stop.
    threads : int
        Solver threads (0 lets the solver decide; ``deterministic`` solves on
        one).  HiGHS sizes one thread pool per process at its first solve:
        keep this the same for every solve of a process.
    max_retries : int
        Re-solves with a larger block gap when real slews push a field out
        of its window.
    slew : SlewModel
        Telescope slew model.
    min_gain : float
        Least probability a field must add to the plan (beyond the fields
        observed before it) to be planned; fields below it are left out,
        whichever scheduler chose them.  0 keeps every field.
    min_coverage : float
        Least coverage of a plan worth publishing; below it the answer is a
        ``not_observable`` document with the reasons.  0 publishes any plan.
    slot_positions : tuple of int
        Slot MILP portfolio: positions per block n of the grids solved
        (each in two phases).
    slot_margin_s : float
        Slack (s) at the end of each slot block for slews longer than the
        estimate.
    detection_lightcurve : str
        Kilonova model (``optimistic``, ``conservative``, ``nsbh`` or a
        light-curve file) of the plans' ``expected_detections`` metric and
        of the detection objective.
    objective : str
        ``coverage`` (maximise the probability covered) or ``detection``
        (then improve the coverage plan's expected detections on the slot
        grids within the coverage floor, ``docs/design/detection.md``;
        never publishes fewer expected detections than the coverage plan).
        Applies to the optimising schedulers (slots, blocks, hybrid);
        ``greedy`` stays the fast coverage heuristic.  The default is
        ``detection``, from the measurement on the 52 shared maps with
        distance layers, the coverage scheduler keeping its 10 s and the
        detection stage getting 4 s more (``time_limit_s`` 14 s,
        ``objective_detection_floor_extra4.txt`` in ``benchmarks/results``):
        mean efficiency x1.20 (optimistic BNS), x1.23 (conservative BNS),
        x1.29 (NSBH) for -0.1 % mean coverage; one map worse beyond its
        Monte Carlo error on one curve (bns_o3/9, optimistic, -0.0016 at
        2.1 sigma: the objective is built from the conservative curve) and
        one from the coverage solver's run-to-run variance.  Splitting a
        10 s budget 6 + 4 instead gave only x1.06 / x1.07 with 5 maps worse
        (``objective_detection_floor.txt``): the coverage stage needs its
        10 s.
    detection_levels : int
        L, distance levels per slot of the detection objective.
    detection_coverage_weight : float
        λ, weight of the coverage tie-break term in the detection objective.
    detection_time_limit_s : float
        With ``objective = "detection"``: the share (s) of ``time_limit_s``
        given to the detection stage, taken from the same total (the
        coverage scheduler gets ``time_limit_s - detection_time_limit_s``);
        it must be less than ``time_limit_s``.
    detection_max_coverage_loss : float
        ε of the coverage floor (X6): a detection plan must cover at least
        ``(1 - ε)`` times what the coverage plan it started from covers
        (relative; after real-overhead timing and the least-gain rule),
        else the coverage plan is kept.  The daemon's supersede rule uses
        the same floor against revision 1.
    exposure_menu_s : tuple of float
        Exposure times (s) the detection stage may give a field (both its
        visits the same), trading area against depth by expected
        detections (``docs/design/detection.md``, section 6).  Empty (the
        default): every visit lasts ``exposure_s``, as before.  Needs
        ``objective = "detection"``; the coverage scheduler before it
        still plans ``exposure_s``.
    bound_time_limit_s : float
        Budget (s) of the interval bound (V1-V4, ``docs/design/milp.md``)
        in the certified coverage bound the optimising schedulers publish
        (``metrics.upper_bound`` = the least of U4 and V); it comes on top
        of ``time_limit_s``, and the hybrid stops early when a plan reaches
        it.  0 publishes the online bound U4 alone.  Default 2 s: on the 56
        shared maps V takes a median 0.05 s, and 9 maps reach 2 s (a time
        limit only loosens V: it is still a bound).
    bound_refine_ends : bool
        The interval bound widens each window only to where the observing
        conditions (loosened by the checker's tolerances) fail, sampled
        every eighth of a time step, instead of by a whole step (V7,
        ``docs/design/milp.md``): a tighter bound (``bns_o3/14``: 0.640 to
        0.566) for 0.1-1 s more of Sun and Moon positions.  Default false.
    hybrid_blocks : bool
        The hybrid runs the paper's block MILP as its last coverage stage
        (when ``MIN_BLOCKS_S`` is left, for at most ``BLOCKS_LIMIT_S``).
        Default false: on the 56 shared maps, side by side with the default
        optimisation, it took a median 0.86 s and changed nothing beyond its
        error (coverage -0.0001 +- 0.0004, expected detections +0.0001 +-
        0.0003, executed coverage -0.0016 +- 0.0013;
        ``benchmarks/quality/hybrid_stage_value.py``).  ``--solver blocks`` runs it
        alone whatever this says.
    hybrid_paced_slots : bool
        The hybrid also plans greedy and the slot grids at the cadence ZTF's
        scheduler keeps, ``cadence_s`` plus the queue windows' 120 s margin
        (at most ``pair_max_s`` when set; Q11, Q19 in
        ``docs/design/executed.md``), after its slot stage and
        for at most ``PACED_SLOTS_LIMIT_S``; its choice (Q15) weighs that plan
        by the coverage executed.  Pairs of filters only.  Default true.
    hybrid_lns : bool
        The hybrid runs its LNS re-solves (H1-H5, ``docs/design/milp.md``)
        after its slot stages.  Default true.
    deterministic : bool
        The budgets (``time_limit_s``, ``detection_time_limit_s``,
        ``bound_time_limit_s``) count work, not wall time (:mod:`.budget`,
        A1-A5 in ``docs/design/milp.md``): HiGHS's own progress and fixed
        costs per Python step, one solver thread, so a plan depends only on
        its inputs and this configuration, not on the machine's load (a
        work second is about a second of the reference machine, quiet).
        Default true; a caller's wall-clock stop (the daemon's
        ``job_deadline_s``, ``mushrooms plan --deadline``) still ends it.
    telescopes : tuple of str
        The telescopes planned: shipped names (``ztf``, ``ls4``, ``winter``,
        ``decam``; ``mushrooms telescopes`` lists them) or paths of
        description files (``docs/design/telescopes.md``).  A plan is made
        for the first; ``mushrooms plan`` plans each alone (phase 2), each
        with :meth:`for_telescope`'s defaults.  Default ``("ztf",)``,
        recorded by a plan only when it differs, so ZTF plan ids are as before.

    Examples
    --------
    The defaults, and a changed copy (the config is frozen):

    >>> import dataclasses
    >>> cfg = PlanningConfig()
    >>> cfg.solver, cfg.objective, cfg.nside, cfg.filters
    ('hybrid', 'detection', 256, ('g', 'r'))
    >>> dataclasses.replace(cfg, solver="greedy", nside=64).solver
    'greedy'

    A value outside its range is refused, with every problem in one line:

    >>> PlanningConfig(nside=100)
    Traceback (most recent call last):
    ...
    ValueError: [scheduler] nside must be a power of 2, got 100
    """

    nside: int = setting(256, 16, 1024, power_of_two=True,
                         why="16: 3.7 deg pixels, still finer than a ZTF field (6.9 deg); 1024: 12.6 M pixels, 0.1 GB per sky array")
    horizon_h: float = setting(24.0, 1, 168, "h", why="at least the two visits of a block; a kilonova fades within a week")
    nights: int = setting(1, 1, 7, why="1: one plan over horizon_h; a kilonova fades within a week")
    revisit: bool = False
    time_step_s: float = setting(120.0, 10, 900, "s",
                                 why="windows to 10 s are finer than any exposure; 900 s is three 300 s exposures")
    sun_alt_max_deg: float = setting(-12.0, -18, 0, "deg", why="astronomical twilight to sunset")
    airmass_max: float = setting(2.5, 1, 3, why="zenith to 19 deg altitude (P48 observes above 20 deg)")
    ha_max_h: float = setting(5.95, 0.5, 12, "h", why="the P48 reaches 5.95 h")
    moon_sep_min_deg: float = setting(20.0, 0, 90, "deg")
    dec_min_deg: float = setting(-31.0, -90, 90, "deg", why="less than dec_max_deg")
    dec_max_deg: float = setting(87.5, -90, 90, "deg")
    exposure_s: float = setting(300.0, 1, 3600, "s", why="ZTF ToO exposures are 30-300 s")
    filters: tuple[str, ...] = ("g", "r")
    cadence_s: float = setting(1800.0, 0, 43200, "s", lo_open=True, why="up to half a day between two visits")
    pair_max_s: float = setting(0.0, 600, 604800, "s", off=0,
                                why="0: one night (12 h); at least cadence_s, (k − 1) × cadence_s for k filters")
    filter_change_s: float = setting(120.0, 0, 900, "s")
    slew_estimate_s: float = setting(10.0, 0, 600, "s")
    n_fields: int | None = setting(None, 1, 5000, why="unset: sized from the horizon; ZTF's grids hold 1 778 fields")
    n_blocks_max: int = setting(6, 1, 48)
    min_block_size: int = setting(0, 0, 500, why="0: the paper's cadence rule")
    penalty: float = setting(0.0, 0, 1, why="probability units")
    block_gap_s: float = setting(0.0, 0, 7200, "s")
    solver: str = "hybrid"
    milp_backend: str = "auto"
    time_limit_s: float = setting(14.0, 0, 3600, "s", lo_open=True, why="an alert's plan is wanted within minutes")
    mip_gap: float = setting(0.01, 0, 1, why="relative gap")
    threads: int = setting(0, 0, 256, why="0: the solver decides")
    max_retries: int = setting(3, 0, 20)
    slew: SlewModel = field(default_factory=SlewModel)
    min_gain: float = setting(ZTF_THRESHOLDS["min_gain"], 0, 1, hi_open=True, why="probability")
    min_coverage: float = setting(ZTF_THRESHOLDS["min_coverage"], 0, 1, hi_open=True, why="probability")
    slot_positions: tuple[int, ...] = setting((6, 7, 5, 8), 1, 50, why="each element")
    slot_margin_s: float = setting(30.0, 0, 600, "s")
    detection_lightcurve: str = "conservative"
    objective: str = "detection"
    detection_levels: int = setting(8, 1, 64)
    detection_coverage_weight: float = setting(0.05, 0, 10)
    detection_time_limit_s: float = setting(4.0, 0, 3600, "s", lo_open=True, why="less than time_limit_s")
    detection_max_coverage_loss: float = setting(0.02, 0, 1, hi_open=True, why="relative")
    exposure_menu_s: tuple[float, ...] = setting((), 1, 3600, "s", why="each element; empty: every visit exposure_s")
    bound_time_limit_s: float = setting(2.0, 0, 600, "s", why="0: the online bound U4 alone")
    bound_refine_ends: bool = False
    hybrid_blocks: bool = False
    hybrid_paced_slots: bool = True
    hybrid_lns: bool = True
    deterministic: bool = True
    max_open_shutter_s: float | None = setting(None, 1, 604800, "s",
                                               why="unset: no cap; at least one exposure, at most a week of exposures")
    telescopes: tuple[str, ...] = DEFAULT_TELESCOPES

    def __post_init__(self) -> None:
        require_finite(self, "scheduler")
        problems = []
        if not isinstance(self.slew, SlewModel):  # a hand-built config; a file's is refused as "expected a table"
            problems.append(f"slew must be a SlewModel (the [scheduler.slew] table), got {self.slew!r}")
        problems += telescope_problems(self)
        problems += grid_problems(self) + scheduler_problems(self) + stage_problems(self)  # config_checks
        if problems:
            raise ValueError("[scheduler] " + "; ".join(problems))

    def record(self) -> dict[str, Any]:
        """The configuration as the plan records it (and its plan id hashes).

        ``exposure_menu_s`` appears only when set, ``revisit``,
        ``bound_refine_ends``, ``hybrid_blocks``, ``hybrid_paced_slots`` and
        ``deterministic`` only when true,
        ``hybrid_lns`` only when false, ``telescopes`` only when not
        ``["ztf"]``, so a plan without them has the
        same document and the same plan id as before they existed.
        """
        out = dataclasses.asdict(self)
        for key in RECORDED_WHEN_SET:
            if not out[key]:
                del out[key]
        for key in RECORDED_WHEN_CLEARED:
            if out[key]:
                del out[key]
        if tuple(out["telescopes"]) == DEFAULT_TELESCOPES:
            del out["telescopes"]
        return out

    @property
    def telescope(self) -> str:
        """The telescope this configuration plans: the first of ``telescopes`` (a name or a description file)."""
        return self.telescopes[0]

    @classmethod
    def for_telescope(cls, telescope: Any, values: Mapping[str, Any] = {}) -> "PlanningConfig":
        """The configuration planning ``telescope`` (a :class:`~.instruments.TelescopeDescription`).

        Starts from the description's defaults (``[limits]``, ``[planning]``,
        ``[overheads]``: :func:`~.instruments.defaults.planning_defaults`); a
        key ``values`` (a ``[scheduler]`` table) sets wins, ``slew`` key by
        key; ``telescopes`` becomes this one alone.  For ZTF: the defaults.
        One exception: a key the description sets, given in ``values`` with
        ZTF's default value, is the shipped ``config.toml`` writing out ZTF's
        defaults, not a choice for another telescope: the description's
        value stays (give another value to override it).

        Raises
        ------
        ValueError
            One line naming every bad key, as :meth:`from_mapping`.
        """
        from .instruments.defaults import planning_defaults, telescope_entry

        own = planning_defaults(telescope)
        ztf = telescope.name == "ztf"
        table = {**own, **{k: v for k, v in values.items()
                           if k != "telescopes" and (ztf or k not in own or not _ztf_default(k, v))}}
        if isinstance(values.get("slew"), Mapping):
            table["slew"] = {**own["slew"], **{k: v for k, v in values["slew"].items()
                                               if ztf or k not in own["slew"] or not _ztf_default(k, v, SlewModel)}}
        table["telescopes"] = [telescope_entry(telescope)]
        return cls._from_table(table)

    @property
    def pair_separation_s(self) -> float:
        """(P10) A pair's largest separation (s): ``pair_max_s``, or one night when it is 0."""
        return float(self.pair_max_s) if self.pair_max_s else ONE_NIGHT_PAIR_S

    @property
    def horizon_s(self) -> float:
        """Planning horizon in seconds."""
        return self.horizon_h * 3600.0

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> "PlanningConfig":
        """Build from a ``[scheduler]`` table; unknown keys are an error.

        A table whose first telescope is not ZTF is that telescope's
        configuration (:meth:`for_telescope`), keeping every name of
        ``telescopes``: what a plan is made for, and what a plan made for it
        records (the same configuration again).

        Parameters
        ----------
        values : mapping
            Keys are attribute names; ``slew`` may be a nested table.
        """
        names = values.get("telescopes")
        if (isinstance(names, (list, tuple)) and names and isinstance(names[0], str) and names[0] != "ztf"
                and not telescope_problems(_names_only(names))):
            from .instruments.loader import load_description

            first = cls.for_telescope(load_description(names[0]), values)
            return dataclasses.replace(first, telescopes=tuple(names))
        return cls._from_table(values)

    @classmethod
    def _from_table(cls, values: Mapping[str, Any]) -> "PlanningConfig":
        """:meth:`from_mapping` without a telescope's defaults."""
        kwargs = dict(values)
        if isinstance(kwargs.get("slew"), Mapping):
            kwargs["slew"] = dataclass_from_table(SlewModel, kwargs["slew"], "scheduler.slew")
        return dataclass_from_table(cls, kwargs, "scheduler")
