"""From a notice (or an operator's trigger) to a durable decision and a planning job.

``accept``    parse, policy, decision and store in one transaction (``Intake``)
``pipeline``  ``NoticePipeline``: intake, the planning stages, the sink
``trigger``   ``mushrooms trigger``: the trigger directory, the pid lock
``replay``    replaying stored notices through the same pipeline

Imports nothing, so a caller loads only the module it needs.
"""
