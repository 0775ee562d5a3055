"""Identify the joint from a record: fit the damping law, compare the laws, bound the estimates.

ROS-free (numpy and scipy); every candidate trajectory is simulated by the core.

>>> from pendulum_sim.identify import fit, compare          # doctest: +SKIP
>>> best = compare(t, position)[0]                          # doctest: +SKIP
>>> best.model, best.params['omega0'], best.ci95['omega0']  # doctest: +SKIP
"""
from __future__ import annotations

from .errors import IdentifyError
from .fit import Fit, Record, compare, compare_records, fit, fit_records, prepare
from .laws import LAWS, MODELS

__all__ = ['LAWS', 'MODELS', 'Fit', 'IdentifyError', 'Record', 'compare', 'compare_records',
           'fit', 'fit_records', 'prepare']
