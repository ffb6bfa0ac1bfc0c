"""The long-running service, in rooms by concern.

Built from plain objects by the command layer (:mod:`mushrooms.tool`): the
tools load the configuration (:mod:`mushrooms.tool.config`) and hand the
daemon its sections (``Service(config, paths)``, ``run_trigger(..., config,
paths)``, ``replay_notices(..., config)``); no module here imports the config
loader or ``argparse`` (``tests/test_architecture.py``).  This ``__init__``
and the subpackages' import nothing, so the tool layer reads :mod:`.settings`
cheaply.

Rooms (each a subpackage; modules imported lazily by the CLI):

``kafka``       the GCN consumer, the outbound topic, librdkafka's log
``intake``      notice or trigger -> durable decision -> planning job; replays
``planning``    the job runner, first plans and revisions, re-plans, an event's nights, the warm sky
``loop``        executed observations: read, store, poll (it asks planning for the re-plans)
``submission``  plans to ZTF's queue and SkyPortal
``state``       the SQLite state file, one owner of the per-event truth
``ops``         metrics, health, systemd notify, the webhook

At the top, what ties them: ``service`` (``mushrooms run``: lifecycle and stop
order) with what it hands off, ``signals`` (the flags the handlers set),
``timers`` (heartbeat, watchdog, re-warm, pruning, the loop's polls),
``reload`` (SIGHUP) and ``drain`` (a back-off thread per outbound queue);
``settings`` (``[daemon]``, ``[kafka]``, ``[outbound]``, runtime paths),
``sections`` (``ServiceConfig``, a Protocol), ``wiring`` (store, sink and
pipeline for ``service`` and ``trigger``), ``sinks`` (the directory sink),
``credentials`` (secrets from the environment or systemd credentials).
"""
