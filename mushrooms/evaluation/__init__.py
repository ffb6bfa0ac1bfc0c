"""Evaluation of the scheduler, kept apart from it: benchmark, detection efficiency, baselines.

Only the benchmark and studies use this package; ``mushrooms.scheduler_core``,
``mushrooms.handlers`` and ``mushrooms.daemon`` never import it
(tests/test_architecture.py checks).  It imports the shared kilonova source
model from :mod:`mushrooms.scheduler_core.source`.
"""
