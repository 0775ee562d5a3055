"""The numerical core of pendulum_sim: model, integrators, stability guard, energy, analysis.

Pure Python and numpy; nothing here imports ROS. Many pendulums at once:
``from pendulum_sim.core.sweep import sweep`` (kept out of this namespace: it is also a module).

>>> from pendulum_sim.core import PendulumParams, simulate
>>> run = simulate(PendulumParams(gamma=1.0, n=1), phi0=2.0, dphi0=0.0, t_end=20.0, h=1e-3)
"""
from __future__ import annotations

from .errors import IntegratorError, ModelError, PendulumError
from .guard import GuardStats, StabilityGuard
from .methods import METHODS, Method, get_method
from .model import (
    PendulumParams,
    dissipated_power,
    energy,
    input_power,
    kinetic_energy,
    potential_energy,
)
from .simulate import Trajectory, simulate
from .stepper import Stepper

__all__ = [
    'METHODS',
    'GuardStats',
    'IntegratorError',
    'Method',
    'ModelError',
    'PendulumError',
    'PendulumParams',
    'StabilityGuard',
    'Stepper',
    'Trajectory',
    'dissipated_power',
    'energy',
    'get_method',
    'input_power',
    'kinetic_energy',
    'potential_energy',
    'simulate',
]
