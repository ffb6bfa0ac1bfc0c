"""The long-running service: consumer loop, jobs, state store, sinks, signals.

Modules (imported lazily by the CLI; this package imports nothing heavy so
that ``mushrooms.config`` can read :mod:`.settings` cheaply):

``settings``     ``[daemon]``, ``[kafka]``, ``[outbound]`` tables, runtime paths
``service``      ``mushrooms run``: the main loop, signals, heartbeat, watchdog
``consumer``     gcn-kafka consumer, manual offset commits
``jobs``         one planning job per superevent, supersede, deadlines, outbox retries
``trigger``      ``mushrooms trigger``, trigger directory, pid lock
``wiring``       effective config, store, sink and pipeline, shared by ``service`` and ``trigger``
``kafka_sink``   outbound Kafka topic (idempotent producer, acks=all)
``notify``       systemd ``sd_notify`` (READY, WATCHDOG, STATUS, STOPPING)
``credentials``  GCN client id/secret from the environment or systemd credentials
``store``, ``sinks``, ``pipeline``, ``replay``  state, directory sink, notice path, replays
"""
