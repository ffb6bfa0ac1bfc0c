"""Which way ZTF's scheduler takes a queue and a target: the rules the executor follows (Q1, Q2, Q3).

Read in ztf_sim (``ZwickyTransientFacility/ztf_sim``, commit c5ab409,
BSD-3-Clause licence; facts cited, no code taken), ``docs/design/executed.md``:

* (Q1) ``simulate.py`` line 128 calls ``Scheduler.check_for_timed_queue_and_switch``
  (``Scheduler.py`` lines 249-268); the ToO switch on line 127 is commented
  out.  From the default queue it walks every queue in the order they were
  added and calls ``set_queue`` on each valid, non-empty one, with no
  ``break``: the **last** such queue in submission order wins
  (``switch = "last"``).  ``"first"`` is what a switch with a ``break``
  would take (the executor's rule before issue 52).
* (Q2) ``ListQueueManager._next_obs`` (``QueueManager.py`` lines 1211-1257)
  computes ``1 / cos(zenith angle)``, negative below the horizon, so a
  target that has set (or not yet risen) within ``|HA| < 5.95 h`` passes
  its airmass cut; ``TelescopeStateMachine.slew_allowed`` (lines 119-129)
  then refuses the slew (altitude < 10 deg), and ``simulate.py`` lines
  191-199 wait ``EXPOSURE_TIME`` (30 s) and choose again: the same target,
  first in list order, until it leaves the checks (``refused = "retry"``).
  ``"skip"`` passes it over like any unobservable target (the old rule).
* (Q3) a list queue whose last target was taken stays the current queue
  while its window is open; in ``simulate.py`` the next choice raises
  ``QueueEmptyError`` (``QueueManager.py`` line 1216) and lines 135-142
  fall back to the default queue, whose survey takes that exposure; only
  then does the switch of Q1 run (``emptied = "survey"``).  A server that
  drives the P48 with ztf_sim's ``Scheduler`` (public code, read for
  issue 52) removes a request when it is sent and runs the ToO switch every
  10 s, so an emptied ToO queue is left for the next open one during its
  last exposure: ``"switch"``, the default, goes straight to the next queue.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["QueueRules", "SWITCHES", "ZTF_SIM_RULES", "SIMULATE_PY_RULES", "FIRST_WINS_RULES", "PRE_ISSUE52_RULES"]

#: ``QueueRules.switch`` values: the last (ztf_sim's main loop) or the first valid queue in submission order.
SWITCHES = ("last", "first")


@dataclass(frozen=True)
class QueueRules:
    """How the scheduler switches queues and treats a target it cannot slew to.

    Attributes
    ----------
    switch : str
        ``last`` (ztf_sim's ``check_for_timed_queue_and_switch``, the
        default) or ``first``: which valid, non-empty queue in submission
        order the default queue hands the telescope to (Q1).
    refused : str
        ``retry`` (ztf_sim): a target that passes ``_next_obs``'s checks
        but whose slew is refused (below 10 deg altitude, Dec < -35 deg)
        holds its queue, retried every ``retry_s``; ``skip``: it is passed
        over (Q2).
    emptied : str
        ``switch`` (default): the next queue is taken at once; ``survey``
        (``simulate.py``): a queue emptied inside its window costs one survey
        exposure before the next queue is taken (Q3).
    retry_s : float
        Wait (s) after a refused slew (ztf_sim ``TelescopeStateMachine.wait``,
        ``EXPOSURE_TIME`` = 30 s).
    """

    switch: str = "last"
    refused: str = "retry"
    emptied: str = "switch"
    retry_s: float = 30.0

    def __post_init__(self) -> None:
        for name, allowed in (("switch", SWITCHES), ("refused", ("retry", "skip")),
                              ("emptied", ("survey", "switch"))):
            if getattr(self, name) not in allowed:
                raise ValueError(f"QueueRules.{name} must be one of {', '.join(allowed)}, "
                                 f"got {getattr(self, name)!r}")
        if not self.retry_s > 0:
            raise ValueError(f"QueueRules.retry_s must be > 0, got {self.retry_s}")


#: The executor's default: ztf_sim's queue switch and refused slews; an emptied queue left at once.
ZTF_SIM_RULES = QueueRules()
#: ``simulate.py`` to the letter: an emptied queue costs a survey exposure too.
SIMULATE_PY_RULES = QueueRules(emptied="survey")
#: The same, but the first valid queue in submission order is taken (a switch with a ``break``).
FIRST_WINS_RULES = QueueRules(switch="first")
#: The executor before issue 52: first-wins, refused targets skipped.
PRE_ISSUE52_RULES = QueueRules(switch="first", refused="skip")
