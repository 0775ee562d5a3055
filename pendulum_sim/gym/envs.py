"""The scalar environments ``pendulum_sim/DampedPendulum-v0`` and ``StepResponse-v0``.

Each is one episode of a :class:`~pendulum_sim.gym.runner.Runner` (what an action does, how
an episode is drawn and ends) over the simulated joint of a scene; the vector environments
(:mod:`pendulum_sim.gym.vector`) run N of the same.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from .errors import GymError
from .render import frame
from .runner import Runner, torques
from .scenario import Scenarios
from .tasks import STEP, SWING_UP, Task

FloatArray = NDArray[np.float64]
RENDER_MODES = ['rgb_array']
_ONE = np.zeros(1, dtype=np.int64)


def make_runner(task: Task, size: int, scene: str | None,
                parameters: Mapping[str, Any] | str | Path | None, integrator: str | None,
                h: float | None, control_period: float | None, render_mode: str | None,
                max_episode_steps: int | None, target: Any,
                episode_metrics: bool = True) -> Runner:
    """Return the runner of ``size`` environments of ``task`` made from the keywords."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise GymError(f'render_mode must be one of {", ".join(RENDER_MODES)} or None, got '
                       f'{render_mode!r}')
    scenarios = Scenarios(scene, parameters, integrator, h, control_period,
                          default_scene=task.scene, defaults=task.defaults,
                          target=task.target if target is None else target)
    if not isinstance(episode_metrics, bool):
        raise GymError(f'episode_metrics must be True or False, got {episode_metrics!r}')
    return Runner(task, scenarios, size, max_episode_steps, episode_metrics)


def spaces_of(runner: Runner) -> tuple[spaces.Box, spaces.Box]:
    """Return one environment's observation and action spaces."""
    low, high = runner.task.observation_bounds()
    limit = runner.max_effort
    return (spaces.Box(low, high, dtype=np.float64),
            spaces.Box(-limit, limit, shape=(1,), dtype=np.float64))


def fps(runner: Runner) -> int:
    """Return the frames per second of real time that show one frame per control period."""
    config = runner.scenarios.first().config
    return max(1, round(1.0 / (int(config.period_steps) * float(config.h))))


class JointEnv(gym.Env[FloatArray, FloatArray]):
    """A Gymnasium environment of the simulated joint (one task; see the subclasses).

    Parameters
    ----------
    scene : str, optional
        A scene name or parameter file (``pendulum_node --scene``); default ``controller_test``.
    parameters : mapping or path, optional
        Campaign spaces over node parameters (a value, a list or ``{distribution: ...}`` per
        name, as a campaign file's ``parameters``), drawn per episode as ``pendulum_campaign``
        draws them, over the task's own; or a campaign file (its parameters, target, scene).
    integrator : str, optional
        ``rk4``, ``midpoint`` or ``euler`` (the core's explicit methods).
    h : float, optional
        The integration step (s).
    control_period : float, optional
        The time an action is held (s), a whole number of steps ``h``.
    render_mode : str, optional
        ``'rgb_array'``: :meth:`render` returns a frame of the pendulum.
    max_episode_steps : int, optional
        Truncate each episode after this many steps (``gymnasium.make`` truncates with its
        ``TimeLimit`` wrapper instead, at the registered 1000 or 500).
    target : number, list or mapping, optional
        ``StepResponse``: the target's space (rad), as a campaign file's ``target``.
    episode_metrics : bool
        ``DampedPendulum``: keep each episode's samples (24 bytes an environment a step)
        and put its swing-up metrics in ``info`` at the step it terminates or truncates
        (default True).

    Notes
    -----
    Observations are float64, the joint's state unrounded (Pendulum-v1's are float32).

    At the step a ``DampedPendulum`` episode ends (terminated, or truncated by the
    environment's own ``max_episode_steps``), ``info`` also holds the fields of its
    :class:`~pendulum_sim.testing.swing_up.metrics.SwingUpMetrics` (``success``,
    ``swing_up_time``, ``stays``, ``settle_time``, ``energy``, ...; the runner's module says
    over which samples); no other step carries them. ``gymnasium.make`` gives the environment
    the registered length (1000), so its episodes end there with them; a ``TimeLimit`` of
    another length (``gymnasium.make(id, max_episode_steps=N)``) truncates outside the
    environment, which does not see it: give the length to the environment itself
    (``DampedPendulumEnv(max_episode_steps=N)``, or ``gymnasium.make_vec``, which passes it).
    """

    metadata: dict[str, Any] = {'render_modes': RENDER_MODES, 'render_fps': 100}  # noqa: RUF012
    TASK: Task = SWING_UP

    def __init__(self, *, scene: str | None = None,
                 parameters: Mapping[str, Any] | str | Path | None = None,
                 integrator: str | None = None, h: float | None = None,
                 control_period: float | None = None, render_mode: str | None = None,
                 max_episode_steps: int | None = None, target: Any = None,
                 episode_metrics: bool = True) -> None:
        self._runner = make_runner(self.TASK, 1, scene, parameters, integrator, h,
                                   control_period, render_mode, max_episode_steps, target,
                                   episode_metrics)
        self.observation_space, self.action_space = spaces_of(  # type: ignore[assignment]
            self._runner)
        self.metadata = {'render_modes': RENDER_MODES, 'render_fps': fps(self._runner)}
        self.render_mode = render_mode

    @property
    def runner(self) -> Runner:
        """Return the episode runner (its pendulum, scenarios and episode state)."""
        return self._runner

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[FloatArray, dict[str, Any]]:
        """Start the next episode (episode 0 of ``seed`` when given); return its first state."""
        if options:
            raise GymError(f'reset takes no options, got {sorted(options)}')
        super().reset(seed=seed)
        r = self._runner
        r.reset(_ONE, [seed], self.np_random)
        episode = r.episode(0)
        info = {'seed': r.seeds[0], 'episode': r.index[0], 'target': float(r.target[0]),
                'parameters': {k: episode.values[k] for k in r.scenarios.spec.parameter_names}}
        return r.observe(_ONE)[0], info

    def step(self, action: FloatArray) -> tuple[FloatArray, float, bool, bool, dict[str, Any]]:
        """Apply the torque ``action`` (shape (1,), N m) for one control period."""
        r = self._runner
        r.check_running(0)
        torque = torques(action, (1,))
        obs, reward, terminated, truncated, failed = r.step(torque, _ONE)
        info: dict[str, Any] = {'effort': float(r.pendulums.effort[0])}
        if failed:
            info['failed'] = failed[0]
        if terminated[0] or truncated[0]:
            columns, measured = r.end_info(_ONE)
            if measured[0]:   # as SwingUpMetrics holds them: Python values, NaN math.nan
                for name, values in columns.items():
                    value = values[0].item()
                    info[name] = math.nan if value != value else value
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), info

    def render(self) -> NDArray[np.uint8] | None:
        """Return a frame of the pendulum (``rgb_array``), or None without a render mode."""
        if self.render_mode is None:
            return None
        r = self._runner
        target = float(r.target[0]) if r.task is STEP else None
        return frame(float(r.pendulums.phi[0]), float(r.pendulums.effort[0]), r.max_effort,
                     target)


class DampedPendulumEnv(JointEnv):
    """Swing up and stabilise the damped pendulum (``pendulum_sim/DampedPendulum-v0``).

    Observation ``[cos φ, sin φ, φ']`` (φ = 0 hanging down), action a torque in
    ``[−max_effort, max_effort]`` N m (1 N m by default, less than m g l), reward
    Pendulum-v1's shape (:mod:`pendulum_sim.gym.tasks`). Each episode starts anywhere
    (φ uniform in [−π, π], φ' in [−1, 1] rad/s) as Pendulum-v1's does.
    """

    TASK = SWING_UP

    def __init__(self, *, scene: str | None = None,
                 parameters: Mapping[str, Any] | str | Path | None = None,
                 integrator: str | None = None, h: float | None = None,
                 control_period: float | None = None, render_mode: str | None = None,
                 max_episode_steps: int | None = None, episode_metrics: bool = True) -> None:
        super().__init__(scene=scene, parameters=parameters, integrator=integrator, h=h,
                         control_period=control_period, render_mode=render_mode,
                         max_episode_steps=max_episode_steps, episode_metrics=episode_metrics)


class StepResponseEnv(JointEnv):
    """Track a target angle (``pendulum_sim/StepResponse-v0``).

    Observation ``[cos φ, sin φ, φ', φ*]``, action a torque in ``[−max_effort, max_effort]``
    N m, reward the test bench's −iae per period (:mod:`pendulum_sim.gym.tasks`). Each
    episode starts at rest at φ = 0; its target φ* is drawn from ``target`` (a number, a list
    or a distribution as a campaign's ``target``; default uniform in [−0.5, 0.5] rad).
    """

    TASK = STEP
