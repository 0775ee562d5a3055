"""The vector environments: N episodes of one task, every period one batched core call.

``gymnasium.make_vec('pendulum_sim/DampedPendulum-v0', num_envs=N,
vectorization_mode='vector_entry_point')`` makes one. The N pendulums advance together
through one prepared :class:`pendulum_sim.core.sweep.Sweep` (a
:class:`pendulum_sim.joint.lockstep.Lockstep`, the test bench's batches' as well) and the
episodes are those of N scalar environments (:mod:`pendulum_sim.gym.runner`): with
``reset(seed=s)`` environment ``i`` is the scalar environment reset with ``seed=s + i``, as
Gymnasium's ``SyncVectorEnv`` seeds its environments, bit for bit.

Autoreset is Gymnasium 1.x's default, next-step (``AutoresetMode.NEXT_STEP``): the step after
an environment's episode ended ignores its action, resets it (the next episode of its seed)
and returns its first observation with reward 0 and neither terminated nor truncated. The
environments that reset in a step are drawn and started together, over arrays (issue 38).

At the step ``DampedPendulum`` episodes end, ``info`` holds their swing-up metrics as
Gymnasium's vector environments hold a key some environments have (``VectorEnv._add_info``):
per field an array over the N environments (bool, float or int as the field; 0 where an
environment's episode did not end) and its mask ``_field``, True for the environments whose
episode ended and was measured; each environment's entries are those the scalar environment
gives the same episode.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from .envs import RENDER_MODES, fps, make_runner, spaces_of
from .errors import GymError
from .render import frame
from .runner import Runner, torques
from .tasks import STEP, SWING_UP, Task

FloatArray = NDArray[np.float64]


class JointVectorEnv(VectorEnv[FloatArray, FloatArray, FloatArray]):
    """N environments of one task (keywords as :class:`~pendulum_sim.gym.envs.JointEnv`)."""

    TASK: Task = SWING_UP

    def __init__(self, num_envs: int = 1, *, scene: str | None = None,
                 parameters: Mapping[str, Any] | str | Path | None = None,
                 integrator: str | None = None, h: float | None = None,
                 control_period: float | None = None, render_mode: str | None = None,
                 max_episode_steps: int | None = None, target: Any = None,
                 episode_metrics: bool = True) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise GymError(f'num_envs must be a positive integer, got {num_envs!r}')
        self._runner = make_runner(self.TASK, num_envs, scene, parameters, integrator, h,
                                   control_period, render_mode, max_episode_steps, target,
                                   episode_metrics)
        self.num_envs = num_envs
        self.single_observation_space, self.single_action_space = spaces_of(self._runner)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.metadata = {'render_modes': RENDER_MODES, 'render_fps': fps(self._runner),
                         'autoreset_mode': AutoresetMode.NEXT_STEP}
        self.render_mode = render_mode
        self._all = np.arange(num_envs, dtype=np.int64)
        self._autoreset = np.zeros(num_envs, dtype=bool)

    @property
    def runner(self) -> Runner:
        """Return the episode runner of the N environments."""
        return self._runner

    def reset(self, *, seed: int | Sequence[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[FloatArray, dict[str, Any]]:
        """Start every environment's next episode; ``seed`` s seeds environment i with s + i."""
        if options:
            raise GymError(f'reset takes no options, got {sorted(options)}')
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)  # type: ignore[arg-type]
            if len(seeds) != n:
                raise GymError(f'reset needs one seed per environment: got {len(seeds)} for '
                               f'{n} environments')
        super().reset(seed=seeds[0])
        self._runner.reset(self._all, seeds, self.np_random)
        self._autoreset[:] = False
        r = self._runner
        return r.observe(self._all), {'seed': np.array(r.seeds),
                                      'episode': np.array(r.index),
                                      'target': r.target.copy()}

    def step(self, actions: FloatArray) -> tuple[  # type: ignore[override]
            FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """Apply each environment's torque for one control period (autoreset: next step)."""
        r = self._runner
        if any(i < 0 for i in r.index):
            raise GymError('step() before reset(): call reset() first')
        torque = torques(actions, (self.num_envs, 1))
        resetting = np.flatnonzero(self._autoreset)
        live = np.flatnonzero(~self._autoreset)
        if resetting.size:   # every environment that ended, in one draw and one start
            r.reset(resetting, None, self.np_random)
        obs = np.empty((self.num_envs, r.task.size))
        reward = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        failed: dict[int, str] = {}
        if live.size:
            (obs[live], reward[live], terminated[live], truncated[live],
             failed) = r.step(torque[live], live)
        if resetting.size:
            obs[resetting] = r.observe(resetting)
        self._autoreset = terminated | truncated
        infos: dict[str, Any] = {'effort': r.pendulums.effort.copy()}
        if failed:
            infos['failed'] = np.array([failed.get(i, '') for i in range(self.num_envs)],
                                       dtype=object)
            infos['_failed'] = np.array([i in failed for i in range(self.num_envs)])
        ended = np.flatnonzero(self._autoreset)
        if ended.size:   # Gymnasium's vector info: per key an array and its mask '_key'
            columns, measured = r.end_info(ended)
            if measured.any():
                mask = np.zeros(self.num_envs, dtype=bool)
                mask[ended[measured]] = True
                for name, values in columns.items():
                    infos[name] = np.zeros(self.num_envs, dtype=values.dtype)
                    infos[name][ended[measured]] = values[measured]
                    infos[f'_{name}'] = mask.copy()
        return obs, reward, terminated, truncated, infos

    def render(self) -> tuple[NDArray[np.uint8], ...] | None:
        """Return one frame per environment (``rgb_array``), or None without a render mode."""
        if self.render_mode is None:
            return None
        r = self._runner
        p = r.pendulums
        return tuple(frame(float(p.phi[i]), float(p.effort[i]), r.max_effort,
                           float(r.target[i]) if r.task is STEP else None)
                     for i in range(self.num_envs))


class DampedPendulumVectorEnv(JointVectorEnv):
    """N environments of ``pendulum_sim/DampedPendulum-v0``."""

    TASK = SWING_UP

    def __init__(self, num_envs: int = 1, *, scene: str | None = None,
                 parameters: Mapping[str, Any] | str | Path | None = None,
                 integrator: str | None = None, h: float | None = None,
                 control_period: float | None = None, render_mode: str | None = None,
                 max_episode_steps: int | None = None, episode_metrics: bool = True) -> None:
        super().__init__(num_envs, scene=scene, parameters=parameters, integrator=integrator,
                         h=h, control_period=control_period, render_mode=render_mode,
                         max_episode_steps=max_episode_steps, episode_metrics=episode_metrics)


class StepResponseVectorEnv(JointVectorEnv):
    """N environments of ``pendulum_sim/StepResponse-v0``."""

    TASK = STEP
