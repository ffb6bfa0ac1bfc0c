"""Fixtures of the service tests (defined in daemon_helpers)."""

from daemon_helpers import broker, daemons  # noqa: F401  (pytest fixtures)
