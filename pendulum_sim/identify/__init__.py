"""Identify the joint from a record: fit the damping law, compare the laws, bound the estimates.

ROS-free (numpy and scipy); every candidate trajectory is simulated by the core. A free swing
fixes ω0 and the damping; a record driven by a known effort fixes the physical joint (inertia,
m g l, damping, friction in N m, a torque offset and the dead time), fitted over windows
re-anchored on the measurement, several records of one joint together; ``validate`` asks how a
fit predicts a record it was not fitted to.

>>> from pendulum_sim.identify import fit, compare          # doctest: +SKIP
>>> best = compare(t, position)[0]                          # doctest: +SKIP
>>> best.model, best.params['omega0'], best.ci95['omega0']  # doctest: +SKIP
>>> joint = fit(t, position, effort=effort, model='power+coulomb')  # doctest: +SKIP
>>> validate(joint, {'t': t2, 'position': y2, 'effort': u2}).fit_prediction  # doctest: +SKIP
"""
from __future__ import annotations

from .driven_fit import driven_record, fit_sets, joint_fit
from .effort import Effort, from_commands, from_samples
from .errors import IdentifyError
from .fit import Fit, Record, compare, compare_records, fit, fit_records, prepare
from .laws import LAWS, MODELS
from .validate import Validation, validate

__all__ = ['LAWS', 'MODELS', 'Effort', 'Fit', 'IdentifyError', 'Record', 'Validation',
           'compare', 'compare_records', 'driven_record', 'fit', 'fit_records', 'fit_sets',
           'from_commands', 'from_samples', 'joint_fit', 'prepare', 'validate']
