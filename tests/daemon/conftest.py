"""Fixtures of the service tests (defined in daemon_helpers)."""

import pytest

from daemon_helpers import broker, daemons  # noqa: F401  (pytest fixtures)


@pytest.fixture
def loopback():
    """A pytest-httpserver on loopback (``contract_servers.loopback_server``), stopped after the test."""
    from contract_servers import loopback_server

    s = loopback_server()
    yield s
    s.clear()
    s.stop()
