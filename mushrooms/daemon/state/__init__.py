"""The state file: one SQLite owner of the per-event truth.

``store``          ``Store``: notices, decisions, jobs, plans, outbox (the seam ``connection``/``transaction``)
``schema``         the tables and their upgrade steps
``records``        ``Job``, ``NoticeRecord``, ``OutboxMessage``
``file``           file mode, refusals, the single-daemon lock
``executed``       the ``executed`` table
``current_event``  the event's current map, plan, notice and follow-up start (C1-C4)
``views``          read-only queries for ``mushrooms status``, metrics and health

Imports nothing, so a caller loads only the module it needs.
"""
