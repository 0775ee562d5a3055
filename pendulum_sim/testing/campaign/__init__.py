"""Robustness campaigns: many closed-loop episodes over a scenario space, on Dask.

``spec.py`` reads and checks the campaign file, ``scenarios.py`` draws each episode's
parameters from its own seed, ``episode.py`` runs one episode to a table row, ``sandbox.py``
runs a worker's episodes in a watched process of its own (``watch.py``: the law's clock it
watches), ``store.py`` keeps the rows in one SQLite database, ``execute.py`` runs the pending
episodes on a Dask cluster (``cluster.py``: the local one), ``summary.py`` writes the table,
``summary.md`` and the figures, and ``cli.py`` is ``pendulum_campaign``.
"""
