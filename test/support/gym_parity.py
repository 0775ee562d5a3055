"""One environment of a vector env, run as its own scalar env (the parity tests' oracle)."""
from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np


def scalar_run(env_id: str, spaces: dict[str, Any] | None, length: int, seed: int,
               actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Run a scalar env (episodes of ``length`` steps, reset with ``seed``) through ``actions``
    with next-step autoreset, as an environment of a vector env: the action after an episode
    ends is ignored, the env resets and the reward is 0. Return the observations (the first
    reset's first) and the rewards."""
    env = gymnasium.make(env_id, parameters=spaces, max_episode_steps=length)
    obs, _ = env.reset(seed=seed)
    seen, rewards, ended = [obs], [], False
    for a in actions:
        if ended:
            obs, reward, ended = env.reset()[0], 0.0, False
        else:
            obs, reward, terminated, truncated, _ = env.step(a)
            ended = terminated or truncated
        seen.append(obs)
        rewards.append(reward)
    return np.array(seen), np.array(rewards)
