"""The episodes of N environments: seeds, draws, steps, ends, actions; one rule for both envs.

The scalar environment is a runner of one episode, the vector environment a runner of N, so
what an action does, how an episode is drawn and when it ends is decided here once.

Seeding: ``reset(seed=s)`` starts episode 0 of seed ``s``; each ``reset()`` without a seed
starts the next episode of the same seed; the first reset without any seed takes a seed
from the environment's ``np_random``. Episode ``k`` of seed ``s`` runs with the scenario of
episode ``k`` of a campaign seeded ``s`` (:mod:`pendulum_sim.gym.scenario`).

An action is a torque in N m, shape ``(1,)`` per environment. A non-finite torque or an
array of another shape is refused with :class:`GymError`; a finite torque outside
``[−max_effort, max_effort]`` is saturated at the limit, as the joint saturates an effort
command (and as ``Pendulum-v1`` clips its action).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import GymError
from .pendulums import Pendulums, check
from .scenario import Scenarios
from .tasks import Task

FloatArray = NDArray[np.float64]
MAX_SEED = 2**63 - 1


def torques(action: Any, shape: tuple[int, ...]) -> FloatArray:
    """Return ``action`` as torques (N m, flat); GymError for another shape or a non-finite one.

    A shape of more than one row names the first environment whose torque is not finite.
    """
    try:
        arr = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise GymError(f'action must be an array of numbers of shape {shape} (torques in '
                       f'N m), got {action!r}') from None
    if arr.shape != shape:
        raise GymError(f'action must have shape {shape} (torques in N m), got shape '
                       f'{arr.shape}')
    flat = arr.reshape(-1)
    bad = np.flatnonzero(~np.isfinite(flat))
    if bad.size:
        where = f' for environment {int(bad[0])}' if len(shape) > 1 else ''
        raise GymError(f'action must be a finite torque, got {flat[bad[0]]}{where}')
    return flat


class Runner:
    """N environments' episodes of one task over one set of scenarios."""

    def __init__(self, task: Task, scenarios: Scenarios, size: int,
                 max_episode_steps: int | None) -> None:
        if max_episode_steps is not None and (
                isinstance(max_episode_steps, bool) or not isinstance(max_episode_steps, int)
                or max_episode_steps < 1):
            raise GymError(f'max_episode_steps must be a positive integer or None, got '
                           f'{max_episode_steps!r}')
        if scenarios.varies('max_effort'):
            raise GymError('max_effort must be one value: it bounds the action space')
        first = scenarios.first()
        check(first.config)
        limit = float(first.config.max_effort)
        if not np.isfinite(limit):
            raise GymError('max_effort must be finite: it bounds the action space')
        self.task = task
        self.scenarios = scenarios
        self.size = size
        self.max_effort = limit
        self.max_episode_steps = max_episode_steps
        self.pendulums = Pendulums(size)
        self.seeds = [0] * size
        self.index = [-1] * size     # the episode running (-1: none yet)
        self.steps = np.zeros(size, dtype=np.int64)
        self.target = np.zeros(size)
        self.ended = [''] * size     # why the episode ended ('' while it runs)
        self.episodes: list[Any] = [None] * size

    def reset(self, i: int, seed: int | None, rng: np.random.Generator) -> None:
        """Start the next episode of environment ``i`` (episode 0 of ``seed`` when given)."""
        if seed is not None:
            if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not (
                    0 <= seed <= MAX_SEED):
                raise GymError(f'seed must be an integer in [0, {MAX_SEED}], got {seed!r}')
            self.seeds[i], self.index[i] = int(seed), 0
        else:
            if self.index[i] < 0:
                self.seeds[i] = int(rng.integers(0, MAX_SEED))
            self.index[i] += 1
        episode = self.scenarios.episode(self.seeds[i], self.index[i])
        self.pendulums.start(i, episode.config)
        self.episodes[i] = episode
        self.target[i] = episode.target
        self.steps[i] = 0
        self.ended[i] = ''

    def observe(self, live: NDArray[np.int64]) -> FloatArray:
        """Return the observations of the environments ``live``, shape (len, d)."""
        p = self.pendulums
        return np.asarray(self.task.observe(p.phi[live], p.vel[live], self.target[live]))

    def step(self, torque: FloatArray, live: NDArray[np.int64]
             ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_],
                        dict[int, str]]:
        """Take a period of the environments ``live`` (their episodes running).

        Returns their observations, rewards, terminations, truncations and the reasons of
        the joints that failed (those episodes are terminated).
        """
        p = self.pendulums
        phi0, vel0 = p.phi[live].copy(), p.vel[live].copy()
        failed = p.advance(torque, live)
        self.steps[live] += 1
        reward = np.asarray(self.task.reward(phi0, vel0, p.phi[live], p.vel[live],
                                             p.effort[live], self.target[live], p.period))
        terminated = np.array([j in failed for j in live.tolist()], dtype=bool)
        limit = self.max_episode_steps
        truncated = (~terminated & (self.steps[live] >= limit) if limit is not None
                     else np.zeros(live.size, dtype=bool))
        for n, j in enumerate(live.tolist()):
            if terminated[n]:
                self.ended[j] = f'terminated: {failed[j]}'
            elif truncated[n]:
                self.ended[j] = f'truncated after {limit} steps'
        return self.observe(live), reward, terminated, truncated, failed

    def check_running(self, i: int) -> None:
        """Refuse to step environment ``i`` before its first reset or after its episode."""
        if self.index[i] < 0:
            raise GymError('step() before reset(): call reset() first')
        if self.ended[i]:
            raise GymError(f'step() after the episode ended ({self.ended[i]}): call reset() '
                           'first')
