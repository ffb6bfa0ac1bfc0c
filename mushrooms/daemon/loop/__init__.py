"""The executed-observation loop: read what ZTF observed, store it, re-plan the nights that follow.

``poll``      ``ExecutedLoop.poll``: the service's timer job (read, store, re-plan)
``fetch``     ``ExecutedReader``: a file, depot directory or URL to executed exposures

Imports nothing, so a caller loads only the module it needs.
"""
