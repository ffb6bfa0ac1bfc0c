"""The long-running service: consumer loop, jobs, state store, sinks, signals.

Built from plain objects by the command layer (:mod:`mushrooms.tool`): the
tools load the configuration (:mod:`mushrooms.tool.config`) and hand the
daemon its sections (``Service(config, paths)``, ``run_trigger(..., config,
paths)``, ``replay_notices(..., config)``); no module here imports the config
loader or ``argparse`` (``tests/test_architecture.py``).  This ``__init__``
imports nothing, so the tool layer reads :mod:`.settings` cheaply.

Modules (imported lazily by the CLI):

``settings``     ``[daemon]``, ``[kafka]``, ``[outbound]`` tables, runtime paths
``sections``     ``ServiceConfig``: the assembled sections the daemon is handed (a Protocol)
``service``      ``mushrooms run``: the main loop, signals, heartbeat, watchdog
``consumer``     gcn-kafka consumer, manual offset commits
``jobs``         one planning job per superevent, supersede, deadlines, outbox retries
``trigger``      ``mushrooms trigger``, trigger directory, pid lock
``wiring``       store, sink and pipeline, shared by ``service`` and ``trigger``
``kafka_sink``   outbound Kafka topic (idempotent producer, acks=all)
``notify``       systemd ``sd_notify`` (READY, WATCHDOG, STATUS, STOPPING)
``credentials``  GCN client id/secret from the environment or systemd credentials
``store``, ``sinks``, ``pipeline``, ``replay``  state, directory sink, notice path, replays
"""
