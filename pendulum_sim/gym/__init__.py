"""Gymnasium environments of the simulated joint (the ``gym`` extra; no ROS).

Importing this package registers ``pendulum_sim/DampedPendulum-v0`` and
``pendulum_sim/StepResponse-v0`` (scalar and vector entry points) with Gymnasium, so that
``gymnasium.make('pendulum_sim/DampedPendulum-v0')`` works after ``import pendulum_sim.gym``;
without the import, ``gymnasium.make('pendulum_sim.gym:pendulum_sim/DampedPendulum-v0')``
imports it. The package also declares
:func:`~pendulum_sim.gym.registration.register_envs` in the ``gymnasium.envs`` entry
point group, the plugin hook of Gymnasium before 1.0 (Gymnasium 1.x no longer reads entry
points).
"""
from __future__ import annotations

from .bridge import policy_law
from .envs import DampedPendulumEnv, JointEnv, StepResponseEnv
from .errors import GymError
from .registration import ENV_IDS, register_envs
from .vector import DampedPendulumVectorEnv, JointVectorEnv, StepResponseVectorEnv

__all__ = [
    'ENV_IDS',
    'DampedPendulumEnv',
    'DampedPendulumVectorEnv',
    'GymError',
    'JointEnv',
    'JointVectorEnv',
    'StepResponseEnv',
    'StepResponseVectorEnv',
    'policy_law',
    'register_envs',
]

register_envs()
