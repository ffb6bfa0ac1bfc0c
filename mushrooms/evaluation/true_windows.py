"""Window ends refined below the visibility grid step (evaluation view of V7).

The refinement lives in :mod:`mushrooms.scheduler_core.schedulers.bounds.outer_windows`
(the interval bound uses it with ``[scheduler] bound_refine_ends = true``);
this module is the name the benchmarks and tests use.
"""

from __future__ import annotations

from ..scheduler_core.schedulers.bounds.outer_windows import LOOSEN, N_SUB, refined_problem, refined_windows

__all__ = ["refined_windows", "refined_problem", "N_SUB", "LOOSEN"]
