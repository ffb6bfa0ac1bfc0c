"""The telescope as ZTF's scheduler drives it: its timing and how it carries out ToO queues.

:mod:`.timing` holds the P48's overheads as ztf_sim models them (readout,
settle, hour-angle/declination/dome slews, a filter change); :mod:`.executor`
plays a set of ToO list queues the way ZTF's scheduler does (queue switching
by validity window, the first observable target in list order, the survey
taking the time when nothing is observable).  Equations (Q1)-(Q10) of
``docs/design/executed.md``.  Pure functions, no I/O.
:mod:`.slew` is the slew time between two fields the schedulers plan
with (the per-axis trapezoid the checker also applies).
"""

from .executor import ExecutedTarget, QueueSet, execute_queues, queue_set_from_payloads
from .timing import TelescopeTiming, dome_azimuth_deg, exposure_overhead_s

__all__ = ["TelescopeTiming", "exposure_overhead_s", "dome_azimuth_deg", "QueueSet", "ExecutedTarget",
           "queue_set_from_payloads", "execute_queues"]
