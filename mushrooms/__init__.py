"""mushrooms: gravitational-wave alerts to ZTF follow-up plans (MUSHROOMS scheduler).

Subpackages, in the one direction data flows:
``mushrooms.daemon`` -> ``mushrooms.handlers`` -> ``mushrooms.scheduler_core``.
``mushrooms.evaluation`` (benchmark, efficiency, baselines) and the command-line
tools (``mushrooms.tool``, dispatched by ``mushrooms.cli``) sit on top; nothing
below imports them (``tests/test_architecture.py``).
"""

__version__ = "0.1.0"
