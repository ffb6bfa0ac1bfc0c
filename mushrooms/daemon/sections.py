"""What the daemon reads of the assembled configuration: a Protocol, not the config module.

The tool layer loads ``config.toml`` (:mod:`mushrooms.tool.config`) and hands
the daemon the result; the daemon never imports the loader.  Any object with
these sections will do (the tool layer's ``Config`` is one; a test may build
a ``types.SimpleNamespace`` or a dataclass of its own).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from ..handlers.policy import PolicyConfig
    from ..scheduler_core.config import PlanningConfig
    from ..scheduler_core.plan.exports import ExportConfig
    from .loop_settings import LoopConfig
    from .settings import DaemonConfig, KafkaConfig, OutboundConfig
    from .submission.settings import SubmitConfig

__all__ = ["ServiceConfig"]


class ServiceConfig(Protocol):
    """The sections of one configuration, as the service, the trigger and the replay use them.

    Attributes
    ----------
    scheduler, policy, daemon, kafka, outbound, export, submit, loop
        The ``[scheduler]`` ... ``[loop]`` tables, each its layer's own type.
    source : str
        Where it was read from (for the logs).
    """

    @property
    def scheduler(self) -> PlanningConfig: ...

    @property
    def policy(self) -> PolicyConfig: ...

    @property
    def daemon(self) -> DaemonConfig: ...

    @property
    def kafka(self) -> KafkaConfig: ...

    @property
    def outbound(self) -> OutboundConfig: ...

    @property
    def export(self) -> ExportConfig: ...

    @property
    def submit(self) -> SubmitConfig: ...

    @property
    def loop(self) -> LoopConfig: ...

    @property
    def source(self) -> str: ...
