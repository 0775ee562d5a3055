"""The vector env on the joint's lockstep: batched resets, counted periods, scalar parity."""
from __future__ import annotations

import re
from typing import Any

import gymnasium
import numpy as np
import pytest
from gym_parity import scalar_run

import pendulum_sim.gym as pg
from pendulum_sim.gym import GymError
from pendulum_sim.joint.lockstep import LockstepStats
from pendulum_sim.testing.campaign.scenarios import STREAMS_FROM

SWING, STEP = pg.ENV_IDS
# Drawn per episode: the start (the task's), the damping law, and a friction on a log scale.
MIXED = {'gamma': {'distribution': 'uniform', 'low': 0.05, 'high': 0.5},
         'n': [1.5, 0.0, 2.0, 1.0],
         'friction': {'distribution': 'loguniform', 'low': 1e-3, 'high': 0.1}}


def run_vector(env_id: str, actions: np.ndarray, length: int, spaces: dict[str, Any] | None,
               seed: int) -> tuple[np.ndarray, np.ndarray, Any]:
    """Run a vector env of ``actions.shape[1]`` environments; return observations, rewards and
    its lockstep's counters."""
    vec = gymnasium.make_vec(env_id, num_envs=actions.shape[1],
                             vectorization_mode='vector_entry_point', parameters=spaces,
                             max_episode_steps=length)
    obs, _ = vec.reset(seed=seed)
    seen, rewards = [obs], []
    for a in actions:
        obs, reward, *_ = vec.step(a)
        seen.append(obs)
        rewards.append(reward)
    return np.array(seen), np.array(rewards), vec.unwrapped.runner.pendulums.stats


@pytest.mark.parametrize(('env_id', 'spaces'), [(SWING, None), (SWING, MIXED), (STEP, None)])
def test_short_episodes_of_many_envs_reset_together_as_each_scalar_env(
        env_id: str, spaces: dict[str, Any] | None) -> None:
    """Episodes of 4 steps, so most steps autoreset: drawn over arrays (N >= STREAMS_FROM),
    one joint configuration for the task's start draws, one per episode for MIXED."""
    n, steps, length = STREAMS_FROM + 4, 14, 4
    actions = np.random.default_rng(31).uniform(-1.5, 1.5, (steps, n, 1))
    got, got_r, stats = run_vector(env_id, actions, length, spaces, 31)
    for i in range(n):
        mine, mine_r = scalar_run(env_id, spaces, length, 31 + i, actions[:, i])
        assert mine.tobytes() == got[:, i].tobytes(), i
        assert mine_r.tobytes() == got_r[:, i].tobytes(), i
    # Every period of every environment in the sweep: steps 1-4, 6-9 and 11-14 step all N
    # (5 and 10 reset them all), and the sweep is prepared once after each start of all N.
    assert stats == LockstepStats(swept=12 * n, by_joint=0, prepared=3)


def test_a_vector_env_counts_the_periods_its_joints_took_near_the_speed_bound() -> None:
    vec = gymnasium.make_vec(SWING, num_envs=4, vectorization_mode='vector_entry_point',
                             parameters={'max_velocity': 1.2, 'phi0': 0.0, 'dphi0': 0.0})
    obs, _ = vec.reset(seed=0)
    for _ in range(100):
        obs = vec.step(np.where(obs[:, 2:] >= 0.0, 1.0, -1.0))[0]
    stats = vec.unwrapped.runner.pendulums.stats
    assert stats.by_joint > 0 and stats.swept + stats.by_joint == 400


def test_a_refused_draw_of_a_batched_reset_names_the_first_refused_episode() -> None:
    """As the scalar env refuses it; the refused reset leaves every environment as it was."""
    spaces = {'dphi0': {'distribution': 'uniform', 'low': -1.3e4, 'high': 1.3e4}}
    n = 2 * STREAMS_FROM
    refused = []
    for i in range(n):
        try:
            pg.DampedPendulumEnv(parameters=spaces).reset(seed=40 + i)
        except GymError as exc:
            refused.append(str(exc))
    assert refused and refused[0].startswith('episode 0 of seed ')
    assert 'dphi0 must be within +-10000 rad/s' in refused[0]
    vec = pg.DampedPendulumVectorEnv(n, parameters=spaces)
    with pytest.raises(GymError, match=re.escape(refused[0])):
        vec.reset(seed=40)
    assert vec.runner.index == [-1] * n and vec.runner.episodes == [None] * n
