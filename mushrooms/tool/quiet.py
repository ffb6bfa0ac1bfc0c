"""No solver banner in a person's output.

HiGHS (1.16) prints ``Running HiGHS ... Copyright ...`` on standard output the
first time a ``highspy.Highs`` object is made in a process, before any option
can turn it off (``output_flag`` is only read afterwards; ERGO-Code/HiGHS
issues 1702 and 2749).  :func:`silence_solver_banner` makes that first object
with file descriptor 1 pointed at ``/dev/null``, so the banner goes nowhere and
no later solve prints it.
"""

from __future__ import annotations

import os
import sys

__all__ = ["silence_solver_banner", "SOLVING_COMMANDS"]

#: Commands that may run HiGHS.
SOLVING_COMMANDS = ("plan", "bench", "demo", "replay", "run", "trigger", "study", "rehearse")


def silence_solver_banner() -> None:
    """Make the process's first ``highspy.Highs`` with standard output muted (nothing when highspy is absent)."""
    try:
        import highspy
    except ImportError:
        return
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            try:
                highspy.Highs()
            finally:
                os.dup2(saved, 1)
    finally:
        os.close(saved)
