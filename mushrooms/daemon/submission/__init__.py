"""Submission of plans to ZTF's queue (Kowalski) and SkyPortal.

``submitter``  ``Submitter``: the lifecycle of a submission, request by request
``rows``       the ``submissions`` table's rows and status documents
``rules``      what is sent, when, and whether a queue already holds it
``removal``    taking a revision's queues back (and watching for one that may still land)
``remote``     the HTTP clients (``KowalskiQueue``, ``SkyPortalPlans``)
``settings``   ``[submit]`` (``SubmitConfig``)

Imports nothing, so a caller loads only the module it needs.
"""
