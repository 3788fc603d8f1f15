"""``make run`` and ``make run-fleet`` (``python -m tools.run``), by job: ``cli`` (options, the run), ``processes``
(free ports, input checks, ``quadsitl up`` beside the ground station) and ``report`` (problems, tables)."""
