"""The registration of the environments with Gymnasium (ids, entry points, episode lengths)."""
from __future__ import annotations

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
                 max_episode_steps=EPISODE_STEPS[env_id],
                 # The environment truncates there itself as well, so that the step its
                 # episode ends (and the TimeLimit's) carries the episode's metrics.
                 kwargs={'max_episode_steps': EPISODE_STEPS[env_id]})
