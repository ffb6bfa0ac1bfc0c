"""Command-line overrides of the configuration, in one place.

``--allow-mock`` (``replay``, ``run``, ``trigger``, the demo), ``--solver``
(the demo), ``--bootstrap``, ``--outbox`` and ``--state`` (``run``,
``trigger``) change the loaded :class:`~mushrooms.tool.config.Config` for one
process only; the file is never written.  :func:`effective_config` is the
file plus the flags of ``run`` and ``trigger``: the tools build the daemon's
objects from it (``Service(config, paths)``).
"""

from __future__ import annotations

import argparse
import dataclasses

from .config import Config, ConfigError, load_config

__all__ = ["override_config", "effective_config", "require_sink_broker"]


def override_config(config: Config, *, allow_mock: bool = False, solver: str | None = None,
                    bootstrap: str | None = None, outbox: str | None = None,
                    state: str | None = None) -> Config:
    """The configuration with the command line's overrides.

    Parameters
    ----------
    config : Config
        As loaded from the file (or the embedded defaults).
    allow_mock : bool
        Accept mock (``MS``) and test (``TS``) events (``[policy] allow_mock``).
    solver : str, optional
        Scheduler for this run (``[scheduler] solver``).
    bootstrap : str, optional
        ``HOST:PORT`` of a local plaintext broker for input; also the Kafka
        sink's broker when it has none of its own.
    outbox : str, optional
        Directory sink instead of the configured one.
    state : str, optional
        SQLite state file (``[daemon] state_path``).

    Returns
    -------
    Config
        A new configuration; ``config`` is unchanged.
    """
    kafka, outbound, daemon, policy, scheduler = (config.kafka, config.outbound, config.daemon, config.policy,
                                                  config.scheduler)
    if bootstrap:
        kafka = dataclasses.replace(kafka, bootstrap=bootstrap)
        if outbound.sink == "kafka" and not outbound.bootstrap:
            outbound = dataclasses.replace(outbound, bootstrap=bootstrap)
    if outbound.sink == "kafka" and not outbound.bootstrap and kafka.bootstrap:
        outbound = dataclasses.replace(outbound, bootstrap=kafka.bootstrap)
    if outbox:
        outbound = dataclasses.replace(outbound, sink="directory", directory=outbox)
    if state:
        daemon = dataclasses.replace(daemon, state_path=state)
    if allow_mock:
        policy = dataclasses.replace(policy, allow_mock=True)
    if solver:
        scheduler = dataclasses.replace(scheduler, solver=solver)
    return dataclasses.replace(config, kafka=kafka, outbound=outbound, daemon=daemon, policy=policy,
                               scheduler=scheduler)


def effective_config(args: argparse.Namespace, runnable: bool = True) -> Config:
    """Config file (or embedded defaults) with the command-line overrides (:func:`override_config`).

    ``--bootstrap`` selects the local plaintext broker for input (and for the
    Kafka sink when it has no broker of its own); ``--outbox DIR`` selects the
    directory sink; ``--state`` the SQLite file; ``--allow-mock`` accepts
    mock and test events.

    Raises
    ------
    ConfigError
        Also, with ``runnable`` (a command that runs the service's sink), when
        the result cannot run: a Kafka sink without a broker
        (:func:`require_sink_broker`).
    """
    config = override_config(
        load_config(getattr(args, "config", None), getattr(args, "set", None) or ()),
        allow_mock=bool(getattr(args, "allow_mock", False)), bootstrap=getattr(args, "bootstrap", None),
        outbox=getattr(args, "outbox", None), state=getattr(args, "state", None))
    return require_sink_broker(config) if runnable else config


def require_sink_broker(config: Config) -> Config:
    """``config``, unless its Kafka sink has no broker: then :class:`~.config.ConfigError`, one line.

    ``[outbound] bootstrap`` is filled from a local ``[kafka] bootstrap`` or
    ``--bootstrap`` (:func:`override_config`); with GCN as input and no
    broker of its own, the sink cannot be built.  Checked here, on the
    configuration a command runs (``run``, a SIGHUP's reload, ``rehearse``,
    ``preflight``; ``trigger`` when no daemon runs and it plans itself), not
    on the file alone, since the file may leave the broker to the command line.
    """
    if config.outbound.sink == "kafka" and not config.outbound.bootstrap.strip():
        raise ConfigError(f'{config.source}: [outbound] sink = "kafka" needs [outbound] bootstrap (HOST:PORT of '
                          'the broker the plans go to); only a local input broker ([kafka] bootstrap or '
                          '--bootstrap) is taken as it when it is not set')
    return config
