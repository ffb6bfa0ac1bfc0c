"""Why the first plan stays final, in plain words (the ``reason`` of a ``plan_final`` message).

The rule (``docs/design/detection.md`` R1-R3) is the daemon's; this module only
says its verdict as a person reads it, the configuration names in brackets.
"""

from __future__ import annotations

from typing import Any

__all__ = ["first_plan_stands"]


def _pct(p: float) -> str:
    return f"{100.0 * p:.2f} %"


def first_plan_stands(solver: str, better: Any, first: Any, gain: float, objective: str,
                      max_coverage_loss: float) -> str:
    """The sentence: what the optimised plan would have done, against the first plan, and the margin it missed.

    Parameters
    ----------
    solver : str
        The optimising scheduler.
    better, first : Plan
        The optimised plan and the first (published) plan.
    gain : float
        ``[daemon] supersede_min_gain``.
    objective : str
        ``[scheduler] objective``.
    max_coverage_loss : float
        ``[scheduler] detection_max_coverage_loss``.
    """
    c_new, c_old = better.metrics.coverage, first.metrics.coverage
    e_new, e_old = better.metrics.expected_detections, first.metrics.expected_detections
    if objective == "detection" and e_new is not None and e_old is not None:
        return (f"The first plan stands: the optimised {solver} plan would detect a kilonova with probability "
                f"{_pct(e_new)} against {_pct(e_old)} (expected detections) and cover {_pct(c_new)} against "
                f"{_pct(c_old)}; a new revision needs {100 * gain:.1f} points more detections without losing "
                f"more than {100 * max_coverage_loss:.0f} points of coverage (the coverage floor), or as many "
                f"detections with {100 * gain:.1f} points more coverage "
                f"([daemon] supersede_min_gain {gain:g}, [scheduler] detection_max_coverage_loss "
                f"{max_coverage_loss:g}).")
    return (f"The first plan stands: the optimised {solver} plan would cover {_pct(c_new)} against "
            f"{_pct(c_old)}; a new revision needs {100 * gain:.1f} points more ([daemon] supersede_min_gain "
            f"{gain:g}).")
