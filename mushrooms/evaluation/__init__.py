"""Evaluation of the scheduler, kept apart from it: benchmark, detection efficiency, baselines, studies.

A library the tools call: :func:`mushrooms.evaluation.bench.run_bench` (``mushrooms bench``)
and :func:`mushrooms.evaluation.study.run_study` (``mushrooms study``) take plain
settings objects, never a command line or a config file, and print nothing
(progress bars on stderr aside, when asked).
``mushrooms.scheduler_core``, ``mushrooms.handlers`` and ``mushrooms.daemon`` never
import this package, and it imports neither the daemon nor the tools
(tests/test_architecture.py checks).  It imports the shared kilonova source
model from :mod:`mushrooms.scheduler_core.source`.
"""
