"""TEMPORARY re-export shim of :mod:`mushrooms.tool.config` (issue 26).

Kept only for ``mushrooms/evaluation/bench.py``, which still reads ``[bench]``
itself until the evaluation split (issue 26 item 3) moves that reading into
``mushrooms/tool/bench.py``; delete it then.  Everything else imports
:mod:`mushrooms.tool.config`; ``tests/test_architecture.py`` lists the
exception.
"""

from __future__ import annotations

from .tool.config import CONFIG_ENV, Config, ConfigError, load_config, read_config_table, resolve_config_path

__all__ = ["Config", "ConfigError", "load_config", "read_config_table", "resolve_config_path", "CONFIG_ENV"]
