"""Gymnasium environments of the simulated joint (the ``gym`` extra; no ROS).

Importing this package registers ``pendulum_sim/DampedPendulum-v0`` and
``pendulum_sim/StepResponse-v0`` (scalar and vector entry points) with Gymnasium, so that
``gymnasium.make('pendulum_sim/DampedPendulum-v0')`` works after ``import pendulum_sim.gym``;
without the import, ``gymnasium.make('pendulum_sim.gym:pendulum_sim/DampedPendulum-v0')``
imports it. The package also declares :func:`register_envs` in the ``gymnasium.envs`` entry
point group, the plugin hook of Gymnasium before 1.0 (Gymnasium 1.x no longer reads entry
points).
"""
from __future__ import annotations

from .bridge import policy_law
from .envs import DampedPendulumEnv, JointEnv, StepResponseEnv
from .errors import GymError
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

ENV_IDS = ('pendulum_sim/DampedPendulum-v0', 'pendulum_sim/StepResponse-v0')
EPISODE_STEPS = {'pendulum_sim/DampedPendulum-v0': 1000, 'pendulum_sim/StepResponse-v0': 500}
_CLASSES = {'pendulum_sim/DampedPendulum-v0': 'DampedPendulum',
            'pendulum_sim/StepResponse-v0': 'StepResponse'}


def register_envs() -> None:
    """Register the environments with Gymnasium (once; a second call changes nothing)."""
    from gymnasium.envs.registration import register, registry

    for env_id in ENV_IDS:
        if env_id in registry:
            continue
        name = _CLASSES[env_id]
        register(id=env_id, entry_point=f'pendulum_sim.gym.envs:{name}Env',
                 vector_entry_point=f'pendulum_sim.gym.vector:{name}VectorEnv',
                 max_episode_steps=EPISODE_STEPS[env_id])


register_envs()
