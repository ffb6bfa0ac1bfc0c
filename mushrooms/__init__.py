"""mushrooms: gravitational-wave alerts to ZTF follow-up plans (MUSHROOMS scheduler).

Subpackages, in the one direction data flows:
``mushrooms.daemon`` -> ``mushrooms.handlers`` -> ``mushrooms.scheduler_core``.
"""

__version__ = "0.1.0"
