"""The telescope as ZTF's scheduler drives it: its timing and how it carries out ToO queues.

:mod:`.timing` holds the P48's overheads as ztf_sim models them (readout,
settle, hour-angle/declination/dome slews, a filter change); :mod:`.executor`
plays a set of ToO list queues the way ztf_sim's main loop does (queue
switching by validity window to the last valid queue in submission order,
the first target in list order that passes, a target below the horizon
holding its queue, the survey taking the time when nothing passes), under
the rules of :mod:`.rules`.  Equations (Q1)-(Q10) of
``docs/design/executed.md``.  Pure functions, no I/O.
:mod:`.slew` is the slew time between two fields the schedulers plan
with (the per-axis trapezoid the checker also applies).
"""

from .executor import ExecutedTarget, QueueSet, execute_queues, queue_set_from_payloads
from .rules import QueueRules
from .timing import TelescopeTiming, dome_azimuth_deg, exposure_overhead_s

__all__ = ["TelescopeTiming", "QueueRules", "exposure_overhead_s", "dome_azimuth_deg", "QueueSet", "ExecutedTarget",
           "queue_set_from_payloads", "execute_queues"]
