"""The swing-up metrics in ``info`` at the end of an episode, scalar and vector environments."""
from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import pytest

import pendulum_sim.gym as pg
from pendulum_sim.gym import policy_law
from pendulum_sim.gym.examples import energy_swing_up, tracking
from pendulum_sim.testing import SwingUpMetrics, closed_loop, swing_up_metrics
from pendulum_sim.testing.swing_up.metrics import SWING_UP_NAMES

SWING, STEP = pg.ENV_IDS
NEAR_UP = {'phi0': {'distribution': 'uniform', 'low': 2.6, 'high': 3.6}, 'dphi0': 0.0}
PERIOD_NS = 10_000_000   # controller_test: 10 steps of h = 1 ms a period


def metrics_of(info: dict[str, Any]) -> SwingUpMetrics:
    """Return the SwingUpMetrics whose fields ``info`` holds."""
    return SwingUpMetrics(**{name: info[name] for name in SWING_UP_NAMES})


def by_hand(phi: list[float], vel: list[float], effort: list[float]) -> SwingUpMetrics:
    """Return swing_up_metrics of the samples, stamped k T from the episode's start."""
    t = np.arange(len(phi)) * PERIOD_NS / 1e9
    return swing_up_metrics(t, phi, vel, effort, effort_limit=1.0)


def test_an_episode_ends_with_its_swing_up_metrics_in_info_and_no_step_before() -> None:
    steps = 350
    env = pg.DampedPendulumEnv(parameters={'phi0': 0.0, 'dphi0': 0.0},
                               max_episode_steps=steps)
    obs, info = env.reset(seed=0)
    assert not set(SWING_UP_NAMES) & set(info)
    p = env.runner.pendulums
    phi, vel, effort = [p.phi[0]], [p.vel[0]], [p.effort[0]]
    for k in range(steps):
        obs, _, terminated, truncated, info = env.step(energy_swing_up(obs))
        phi.append(p.phi[0])
        vel.append(p.vel[0])
        effort.append(p.effort[0])
        assert info['effort'] == effort[-1]
        if k < steps - 1:
            assert not (terminated or truncated) and not set(SWING_UP_NAMES) & set(info), k
    assert truncated
    got = metrics_of(info)
    assert got == by_hand(phi, vel, effort)
    assert np.array(list(got.as_dict().values()), dtype=float).tobytes() == np.array(
        list(by_hand(phi, vel, effort).as_dict().values()), dtype=float).tobytes()
    # It swung up from hanging (1 N m < m g l: it pumps) and stayed: the test bench's
    # verdict on the same run, its own stamps and effort.
    assert got.success and got.stays and got.swings >= 1 and 2.0 < got.swing_up_time < 3.5
    run = closed_loop(policy_law(energy_swing_up), periods=steps + 1,
                      overrides=env.reset(seed=0)[1]['parameters'])
    assert run.swing_up_metrics() == got


def test_the_vector_envs_metrics_are_each_scalar_envs_in_gymnasiums_vector_info() -> None:
    n, length = 3, 120
    vec: Any = gymnasium.make_vec(SWING, num_envs=n, vectorization_mode='vector_entry_point',
                             parameters=NEAR_UP, max_episode_steps=length)
    obs, _ = vec.reset(seed=7)
    p = vec.unwrapped.runner.pendulums
    seen = [[p.phi.copy(), p.vel.copy(), p.effort.copy()]]
    actions = []
    for k in range(length + 3):   # the episodes' end, then the next ones' first steps
        actions.append(np.array([energy_swing_up(o) for o in obs]))
        obs, _, terminated, truncated, infos = vec.step(actions[-1])
        if k < length:
            seen.append([p.phi.copy(), p.vel.copy(), p.effort.copy()])
        if k == length - 1:
            assert truncated.all()
            ended = infos
        else:
            assert not (terminated | truncated).any() and not set(SWING_UP_NAMES) & set(infos)
    samples = np.array(seen)   # (K + 1, 3, n)
    swung = 0
    for i in range(n):
        hand = by_hand(*(samples[:, r, i].tolist() for r in range(3)))
        for name in SWING_UP_NAMES:
            assert ended[f'_{name}'].all()
            value = ended[name][i]   # the batch's row, to the bit
            want = np.asarray(getattr(hand, name), dtype=ended[name].dtype)
            assert np.asarray(value).tobytes() == want.tobytes(), (i, name)
        assert ended['success'].dtype == bool and ended['swings'].dtype == np.int64
        # The scalar environment of the same seed and actions: the same numbers.
        env = pg.DampedPendulumEnv(parameters=NEAR_UP, max_episode_steps=length)
        env.reset(seed=7 + i)
        for a in actions[:length]:
            *_, info = env.step(a[i])
        assert metrics_of(info) == hand
        swung += hand.success
    assert swung >= 2


def test_no_metrics_without_a_goal_or_when_turned_off() -> None:
    off = pg.DampedPendulumEnv(max_episode_steps=2, episode_metrics=False)
    step = pg.StepResponseEnv(max_episode_steps=2)
    for env, policy in ((off, energy_swing_up), (step, tracking)):
        obs, _ = env.reset(seed=1)
        for _ in range(2):
            obs, _, _, truncated, info = env.step(policy(obs))
        assert truncated and not set(SWING_UP_NAMES) & set(info)
    with pytest.raises(pg.GymError, match='episode_metrics must be True or False, got 1'):
        pg.DampedPendulumEnv(episode_metrics=1)  # type: ignore[arg-type]
    # gymnasium.make gives the environment the registered length: its episodes end with the
    # metrics at the step the TimeLimit wrapper truncates them.
    made: Any = gymnasium.make(SWING)
    assert made.unwrapped.runner.max_episode_steps == made.spec.max_episode_steps == 1000
