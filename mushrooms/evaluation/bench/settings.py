"""What a benchmark run is asked to do: the ``[bench]`` section and the row names.

:class:`BenchConfig` is the ``[bench]`` table of ``config.toml`` (a section
of the tools' :class:`~mushrooms.tool.config.Config`, read once with the
other sections); :class:`BenchSettings` is one run: the planning
configuration, that section, and what the command line chose (rows, start,
injections).  A row name is a scheduler of the registry
(:mod:`~mushrooms.scheduler_core.solvers_registry`), optionally with its
objective forced (``hybrid-coverage``), ``service`` (the plan the daemon
publishes: its anytime flow under the configuration), or one of gwemopt's rows; any of our
rows may name an arm, ``<row>@<arm>`` (``hybrid@menu``): the same row planned
under the configuration with the arm's ``[scheduler]`` keys replaced
(``[bench.arms.<arm>]``, or ``mushrooms bench --arm``), e.g. an exposure menu.

A leaf of the evaluation: the standard library and the scheduler's light
modules only, so loading a config imports no numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

from ...scheduler_core.ranges import Range, setting
from ...scheduler_core.solvers_registry import SOLVER_NAMES
from ...scheduler_core.tables import TableError, check_value, dataclass_from_table, shown_value, toml_type

__all__ = ["OURS", "SOLVERS", "GWEMOPT_ROWS", "SERVICE_ROW", "KEYED_ROWS", "OBJECTIVE_SUFFIXES", "ARM_SEPARATOR",
           "row_arm", "keyed_row",
           "ROW_NAMES_VERSION", "MAGLIM_RANGE",
           "BenchConfig", "BenchSettings", "row_solver", "is_row_name", "check_rows"]

#: Our schedulers (the registry's, :mod:`~mushrooms.scheduler_core.solvers_registry`); the others are gwemopt's rows.
OURS = SOLVER_NAMES
#: Rows made by the real gwemopt (``gwemopt-repaired``: its schedule with every rule-breaking exposure removed;
#: ``gwemopt-o4`` and ``gwemopt-skyportal``: the named configurations of :mod:`~mushrooms.evaluation.gwemopt_options`).
GWEMOPT_ROWS = ("gwemopt", "gwemopt-repaired", "gwemopt-o4", "gwemopt-skyportal")
#: The row of what the service publishes for the map: the daemon's anytime flow under the configuration (the fast
#: plan, then ``config.solver``'s plan if it is better by ``supersede_min_gain``; a ``not_observable`` answer below
#: ``min_coverage``), :func:`~.per_map.service_row`.
SERVICE_ROW = "service"
#: Rows that are another row under fixed ``[scheduler]`` keys (an arm with a name of its own): ``service-grg`` is what
#: the service publishes under ZTF's O4 GW sequence g-r-g at 180 s, beside gwemopt-o4's (issue 55).
KEYED_ROWS = {"service-grg": (SERVICE_ROW, {"filters": ["g", "r", "g"], "exposure_s": 180.0})}
SOLVERS = OURS + (SERVICE_ROW, *KEYED_ROWS) + GWEMOPT_ROWS
#: Row names of our schedulers: a plain ``<solver>`` row is what ``make_plan`` publishes under the
#: configuration given (:func:`~mushrooms.scheduler_core.planner.optimise`, ``config.objective``
#: included: under the default ``objective = "detection"`` the scheduler, then the detection stage);
#: ``<solver>-coverage`` and ``<solver>-detection`` force that objective (``-detection`` rows get
#: ``detection_extra_s``).  ``greedy`` is a coverage heuristic under either objective.
OBJECTIVE_SUFFIXES = {"-coverage": "coverage", "-detection": "detection"}
#: ``<row>@<arm>``: one of our rows under the configuration of ``[bench.arms.<arm>]``.
ARM_SEPARATOR = "@"
#: What the rows mean; part of the study's result keys, so rows made under older names are not reused
#: (1: plain rows were the coverage scheduler whatever the objective; 2: a row named after a solver is what the service
#: publishes under the config, objective included; 3: every row has ``coverage_as_executed``, and the ``service`` row;
#: 4: every row has ``coverage_pairs``, ``open_shutter_s`` and ``commit``, gwemopt's named rows, ``service-grg``).
ROW_NAMES_VERSION = 4

#: ``[bench] maglim`` values: AB magnitudes a 300 s ZTF exposure may reach (21.7 in g and r).
MAGLIM_RANGE = Range(10, 30, "mag")


@dataclass(frozen=True)
class BenchConfig:
    """``[bench]``: how ``mushrooms bench`` and ``mushrooms study`` score plans and run gwemopt.

    Attributes
    ----------
    lightcurves : mapping
        Column suffix -> packaged light-curve name or file path; the CSV has
        ``efficiency_<suffix>`` for each (``optimistic``, ``conservative``
        and ``nsbh`` by default).
    maglim : mapping
        Limiting magnitude per filter for a 300 s exposure (AB mag), for the
        first release's scoring (``legacy_scoring``).
    fixed_distance_mpc : float or None
        Distance (Mpc) for maps without distance layers; None = no efficiency there.
    gwemopt_python : str or None
        gwemopt's interpreter (else ``$MUSHROOMS_GWEMOPT_PYTHON``).
    gwemopt_timeout_s : float
        Time limit of one gwemopt run (s).
    gwemopt_cache_dir : str or None
        Directory of cached raw gwemopt schedules (keyed on the sky map's
        bytes and the options passed; format in
        :mod:`~mushrooms.evaluation.gwemopt_baseline`); None = no cache.
    gwemopt_cache_only : bool
        With a cache: never run gwemopt, a map not in the cache gets the
        row status ``not_cached`` (score cached schedules quickly).
    legacy_scoring : bool
        Also score every plan as the first release did (``efficiency_<lc>_v1``).
    reference_solver : str or None
        Paired efficiency differences are against this row (default: the
        first one asked for).
    detection_extra_s : float
        Budget added for ``<solver>-detection`` rows (s): 0 = they run the
        configuration as it is (``time_limit_s`` split between the coverage
        scheduler and the detection stage); > 0 = they run it with
        ``time_limit_s`` raised by this much and ``detection_time_limit_s``
        set to it, so the coverage scheduler keeps the ``-coverage`` rows'
        whole budget.  Plain rows never get it (they are what is published).
    arms : mapping
        Arm name -> ``[scheduler]`` keys that replace the configuration's for
        the rows ``<row>@<arm>`` (``[bench.arms.menu] exposure_menu_s =
        [30, 60, 120, 300, 600]``: ``hybrid@menu`` is the plan ``make_plan``
        publishes under the configuration with that menu).  Empty by default.
    """

    lightcurves: Mapping[str, str] = field(default_factory=lambda: {
        "optimistic": "optimistic", "conservative": "conservative", "nsbh": "nsbh"})
    maglim: Mapping[str, float] = field(default_factory=lambda: {"g": 21.7, "r": 21.7, "i": 21.2})
    fixed_distance_mpc: float | None = setting(None, 1, 20_000, "Mpc", why="unset: no efficiency without distance layers")
    gwemopt_python: str | None = None
    gwemopt_timeout_s: float = setting(1800.0, 1, 86400, "s")
    gwemopt_cache_dir: str | None = None
    gwemopt_cache_only: bool = False
    legacy_scoring: bool = True
    reference_solver: str | None = None
    detection_extra_s: float = setting(0.0, 0, 3600, "s")
    arms: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _check_names("lightcurves", self.lightcurves, str, "a string")
        _check_names("arms", self.arms, Mapping, "a table of [scheduler] keys")
        for name, keys in self.arms.items():
            arm_config(None, name, keys)  # refused here, at load time, not in a worker hours later
        _check_names("maglim", self.maglim, (int, float), "a number")
        for band, mag in self.maglim.items():
            check_value("bench", f"maglim.{band}", mag, MAGLIM_RANGE)

    @classmethod
    def from_mapping(cls, table: Mapping[str, Any]) -> "BenchConfig":
        """From the parsed ``[bench]`` table.

        Raises
        ------
        TableError
            An unknown key, a value of the wrong TOML type or outside its
            range (naming the key, the value and what it takes).
        """
        return dataclass_from_table(cls, table, "bench")


def _check_names(key: str, table: Any, kind: type | tuple[type, ...], expected: str) -> None:
    """Refuse a ``[bench.<key>]`` that is not a table of ``name = <expected>``."""
    if not isinstance(table, Mapping):
        raise TableError(f"[bench] {key} = {shown_value(table)}: expected a table, got {toml_type(table)}",
                         section="bench", key=key, value=table, expected="a table")
    for name, value in table.items():
        if not isinstance(value, kind) or isinstance(value, bool):
            raise TableError(f"[bench] {key}.{name} = {shown_value(value)}: expected {expected}, got "
                             f"{toml_type(value)}", section="bench", key=f"{key}.{name}", value=value,
                             expected=expected)


@dataclass(frozen=True)
class BenchSettings:
    """Everything one benchmark run needs (picklable, sent to worker processes).

    Attributes
    ----------
    config : PlanningConfig
        Planning parameters shared by all solvers (``[scheduler]``).
    bench : BenchConfig
        Scoring and gwemopt settings (``[bench]``).
    solvers : tuple of str
        Row names (:func:`is_row_name`), in CSV order; the first is the
        default reference of the paired differences.
    start_iso : str or None
        One horizon start for all maps (ISO UTC); None = each map's event time.
    n_injections : int
        Kilonova injections per map.
    supersede_min_gain : float
        The ``service`` row's rule: the optimised plan replaces the fast one
        when better by this much (``[daemon] supersede_min_gain``, 0 to 1).
    truth : tuple of float or None
        ``(ra_deg, dec_deg, distance_mpc)`` of a simulated event's injection: the independent scoring
        (:mod:`~mushrooms.evaluation.independent_scoring`) puts its kilonovae there (None: drawn from the map).
    """

    config: Any
    bench: BenchConfig = field(default_factory=BenchConfig)
    solvers: tuple[str, ...] = ("greedy", "slots", "blocks", "hybrid")
    start_iso: str | None = None
    n_injections: int = 10_000
    supersede_min_gain: float = 0.005
    truth: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        check_rows(self.solvers)
        unknown = sorted({a for a in (row_arm(s)[1] for s in self.solvers) if a is not None} - set(self.bench.arms))
        if unknown:
            raise ValueError(f"row arm(s) {', '.join(unknown)} not defined: give [bench.arms.<arm>] or --arm "
                             f"ARM:KEY=VALUE (defined: {', '.join(self.bench.arms) or 'none'})")
        import dataclasses

        for name in self.solvers:  # an arm with a forced objective must make a configuration (a menu: detection)
            row, arm = row_arm(name)
            forced = row_solver(row)[1]
            if arm is not None and forced is not None and self.config is not None:
                try:
                    dataclasses.replace(arm_config(self.config, arm, self.bench.arms[arm]), objective=forced)
                except ValueError as exc:
                    raise ValueError(f"row {name}: {exc}") from None
        if self.n_injections < 1:
            raise ValueError(f"n_injections must be >= 1, got {self.n_injections}")
        if not 0.0 <= self.supersede_min_gain <= 1.0:
            raise ValueError(f"supersede_min_gain must be within 0-1, got {self.supersede_min_gain}")

    @property
    def reference(self) -> str:
        """The row the paired efficiency differences are against."""
        return self.bench.reference_solver or self.solvers[0]


def keyed_row(name: str) -> tuple[str, Mapping[str, Any] | None]:
    """``(row, keys)`` of a keyed row (:data:`KEYED_ROWS`, an arm ignored): ``service-grg`` -> ``("service",
    {"filters": [...], "exposure_s": 180.0})``; any other name -> ``(name, None)``."""
    row = row_arm(name)[0]
    return KEYED_ROWS[row] if row in KEYED_ROWS else (row, None)


def row_arm(name: str) -> tuple[str, str | None]:
    """``(row, arm)`` of a row name: ``hybrid-coverage@menu`` -> ``("hybrid-coverage", "menu")``; arm None
    without ``@``."""
    row, sep, arm = name.partition(ARM_SEPARATOR)
    return (row, arm) if sep else (name, None)


def arm_config(config: Any, name: str, keys: Mapping[str, Any]) -> Any:
    """``config`` with the arm's ``[scheduler]`` keys replaced (checked as ``[bench.arms.<name>]``).

    The keys are checked (names, TOML types, ranges, the configuration's own
    rules) on the default configuration with them; ``config`` None returns
    that configuration (the check alone).

    Raises
    ------
    TableError, ValueError
        An unknown key or a value the ``[scheduler]`` section refuses.
    """
    import dataclasses

    from ...scheduler_core.config import PlanningConfig

    if "slew" in keys:
        raise TableError(f"[bench.arms.{name}] slew: an arm replaces top-level [scheduler] keys only",
                         section=f"bench.arms.{name}", key="slew")
    checked = dataclass_from_table(PlanningConfig, keys, f"bench.arms.{name}")
    if config is None:
        return checked
    return dataclasses.replace(config, **{k: getattr(checked, k) for k in keys})


def row_solver(name: str) -> tuple[str, str | None]:
    """``(scheduler, objective)`` of a row name: ``hybrid-coverage`` -> ``("hybrid", "coverage")``.

    The objective is None for a plain name (the configuration's) and for
    gwemopt's rows.  An arm (``@menu``) is ignored here (:func:`row_arm`).
    """
    name = row_arm(name)[0]
    for suffix, objective in OBJECTIVE_SUFFIXES.items():
        if name.endswith(suffix) and name[:-len(suffix)] in OURS:
            return name[:-len(suffix)], objective
    return name, None


def is_row_name(name: str) -> bool:
    """A row name ``mushrooms bench --solvers`` accepts (an arm only on our rows, its name not checked here)."""
    row, arm = row_arm(name)
    if arm is not None and (not arm or row in GWEMOPT_ROWS):
        return False
    return row in SOLVERS or row_solver(row)[1] is not None


def check_rows(names: Sequence[str]) -> None:
    """Refuse an empty list of row names or one that is not a row name.

    Raises
    ------
    ValueError
        ``unknown solver(s) ...; choose from ...``.
    """
    bad = [s for s in names if not is_row_name(s)]
    if bad or not names:
        raise ValueError(f"unknown solver(s) {', '.join(bad) or '(none)'}; choose from {', '.join(SOLVERS)} "
                         f"(ours also as <solver>{' or <solver>'.join(OBJECTIVE_SUFFIXES)}, and any of ours "
                         f"under an arm as <row>@<arm>)")
