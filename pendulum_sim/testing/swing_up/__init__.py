"""The swing-up task: its metrics, the benchmark's criteria as campaigns, the region of attraction.

``metrics.py`` measures one run (or a batch of runs) of the task: swing up from hanging to
the goal box around upright under a torque limit, then stay there. ``criteria.py`` turns
each criterion of the benchmark into a campaign, ``benchmark.py`` runs them and writes
``benchmark.yaml``, ``roa.py`` draws the region of attraction, ``figures.py`` the comparison
with the reference controllers and ``swing_up.gif``, and ``cli.py`` is
``pendulum_benchmark``.
"""
