"""Robustness campaigns: many closed-loop episodes over a scenario space, on Dask.

``spec.py`` reads and checks the campaign file, ``scenarios.py`` draws each episode's
parameters from its own seed, ``episode.py`` runs one episode to a table row, ``store.py`` keeps
the rows on disk one file per episode, ``execute.py`` runs the pending episodes on a Dask
cluster, ``summary.py`` writes the table, ``summary.md`` and the figures, and ``cli.py`` is
``pendulum_campaign``.
"""
