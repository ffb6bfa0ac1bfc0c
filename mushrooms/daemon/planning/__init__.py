"""The planning jobs of the daemon: first plans, optimised revisions, re-plans.

``jobs``          ``JobRunner`` (one planning job per superevent, supersede, deadlines) and ``OutboxDrain``
``revisions``     ``JobPlanner``: a job's sky map to revision 1, then the optimised revisions
``final_words``   why the first plan stays final, in plain words
``replans``       the re-plan job in the store (record, current plan, next revision)
``replan_stage``  the one stage that plans what remains of a night
``nights``        the nights of an event and their re-plans (the loop's timer asks for them)
``warm``          ``SkyCache``: grid, footprints and per-night visibility kept warm between jobs

Imports nothing, so a caller loads only the module it needs.
"""
