"""What an operator sees of the running daemon: metrics, health, systemd, webhook notices.

``metrics``           ``ServiceMetrics`` (a Prometheus registry of its own)
``health``            ``HealthServer`` (``/metrics``, ``/healthz``, ``/readyz``)
``http_front``        its HTTP server: idle connections cost a descriptor, never a thread
``broker_record``     the brokers' state kept in the state file for ``mushrooms status``
``systemd``           ``sd_notify`` (READY, WATCHDOG, STATUS, STOPPING)
``webhook``           the notification webhook client
``webhook_settings``  ``[notify]`` (``NotifyConfig``)
``announce``          what is announced on the webhook (failed jobs, submission trouble)

Imports nothing, so a caller loads only the module it needs.
"""
