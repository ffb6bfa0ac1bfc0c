"""Defaults of ``mushrooms study``, in a module of their own.

The study (:mod:`mushrooms.evaluation.study`) and its command-line parser
(:mod:`mushrooms.tool.study`) both read them; keeping them here lets
``mushrooms study --help`` build its parser without importing numpy, dask
or the scheduler.
"""

#: Solvers a study plans each map with.
DEFAULT_SOLVERS: tuple[str, ...] = ("greedy", "hybrid")
#: Seed of ``--simulate`` (bayestar-inject / realize-coincs).
DEFAULT_SEED = 2
#: Injections per ``bayestar-realize-coincs`` task of ``--simulate``.
DEFAULT_CHUNK = 50
#: Named population recipes of ``--population`` (defined in :mod:`.recipes`), and the default.
RECIPE_NAMES: tuple[str, ...] = ("o3-bns", "o4", "o4-real")
DEFAULT_RECIPE = "o3-bns"
