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

Episode metrics: for a task with a swing-up goal (``DampedPendulum``) each environment keeps
its episode's samples, as the test bench's closed loop keeps a run's: the state at the start
of each period (``K + 1`` samples after ``K`` steps, the first the reset's), stamped ``t_k =
epoch + k T`` on the joint's nanosecond grid, with the torque the joint applied in the period
before it (0 at the reset). At the step an episode terminates or truncates,
:meth:`Runner.end_info` measures them with
:func:`~pendulum_sim.testing.swing_up.metrics.swing_up_metrics_columns` (goal π, the default
goal box, the joint's ``max_effort`` as the torque limit): the same numbers
``closed_loop(policy_law(policy), periods=K + 1, ...).swing_up_metrics()`` gives the same run.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pendulum_sim.joint.joint import JointConfig, stamp_ns
from pendulum_sim.joint.lockstep import Lockstep, batchable_config, common, common_text
from pendulum_sim.testing.swing_up.metrics import swing_up_metrics_columns

from .errors import GymError
from .scenario import Drawn, Episode, Scenarios
from .tasks import Task

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
MAX_SEED = 2**63 - 1


def check(config: JointConfig) -> None:
    """Refuse a joint configuration the environments cannot step (``batchable_config``'s why)."""
    why = batchable_config(config) or (   # a pulse's time would start again at each reset
        'a disturbance pulse is set' if config.has_disturbance else '')
    if why:
        raise GymError(f'the environment steps the joint of effort commands with an ideal '
                       f'sensor and an explicit method; this scene cannot: {why}')


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
    """N environments' episodes of one task over one set of scenarios.

    The N joints are one :class:`~pendulum_sim.joint.lockstep.Lockstep` (``pendulums``):
    a period of any of them is one batched core call, a reset of any of them one draw over
    arrays and one start. With ``episode_metrics`` (and a task with a goal) each keeps its
    episode's samples for :meth:`end_info`.
    """

    def __init__(self, task: Task, scenarios: Scenarios, size: int,
                 max_episode_steps: int | None, episode_metrics: bool = True) -> None:
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
        self.pendulums = Lockstep(size)
        self.seeds = [0] * size
        self.index = [-1] * size     # the episode running (-1: none yet)
        self.steps = np.zeros(size, dtype=np.int64)
        self.target = np.zeros(size)
        self.ended = [''] * size     # why the episode ended ('' while it runs)
        self._drawn: list[tuple[Drawn, int] | None] = [None] * size
        self.keeps_samples = bool(episode_metrics) and task.goal is not None
        # The episodes' samples: angle, rate, effort (rows), sample k (axis 1), environment.
        self._samples = np.zeros((3, 0, size))

    def episode(self, i: int) -> Episode:
        """Return the episode environment ``i`` runs (its parameters, configuration, target)."""
        held = self._drawn[i]
        if held is None:
            raise GymError('no episode before reset(): call reset() first')
        return held[0].episode(held[1])

    @property
    def episodes(self) -> list[Episode | None]:
        """Return each environment's episode (None before its first reset)."""
        return [None if d is None else d[0].episode(d[1]) for d in self._drawn]

    def reset(self, ids: IntArray, seeds: Sequence[int | None] | None,
              rng: np.random.Generator) -> None:
        """Start the next episode of the environments ``ids`` (episode 0 of a seed given).

        ``seeds`` holds one seed or None per environment (None for all when None). The
        episodes are drawn and checked together before any environment changes.
        """
        wanted = [None] * ids.size if seeds is None else list(seeds)
        new_seeds, new_index = [], []
        for i, seed in zip(ids.tolist(), wanted, strict=True):
            if seed is not None:
                if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not (
                        0 <= seed <= MAX_SEED):
                    raise GymError(f'seed must be an integer in [0, {MAX_SEED}], got {seed!r}')
                new_seeds.append(int(seed))
                new_index.append(0)
            else:
                new_seeds.append(self.seeds[i] if self.index[i] >= 0
                                 else int(rng.integers(0, MAX_SEED)))
                new_index.append(self.index[i] + 1)
        drawn = self.scenarios.episodes(new_seeds, new_index)
        for config, _ in drawn.groups:
            check(config)
        self._check_common(ids, drawn)
        self.pendulums.stop(ids)
        for config, rows in drawn.groups:
            self.pendulums.start(ids[rows], config, drawn.phi0[rows], drawn.dphi0[rows])
        for row, i in enumerate(ids.tolist()):
            self.seeds[i], self.index[i] = new_seeds[row], new_index[row]
            self._drawn[i] = (drawn, row)
            self.ended[i] = ''
        self.target[ids] = drawn.target
        self.steps[ids] = 0
        self._keep(ids)

    def _check_common(self, ids: IntArray, drawn: Drawn) -> None:
        """Refuse episodes that would not step with the others (one h, period, method, guard)."""
        starting = set(ids.tolist())
        running = self.pendulums.common if any(
            c is not None and j not in starting
            for j, c in enumerate(self.pendulums.configs)) else None
        want = running if running is not None else common(drawn.groups[0][0])
        for config, _ in drawn.groups:
            if common(config) != want:
                raise GymError(f'every pendulum of a vector environment steps with one h, '
                               f'control period, integrator and guard; episode has '
                               f'{common_text(common(config))}, the others '
                               f'{common_text(want)}')

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
        self._keep(live)
        reward = np.asarray(self.task.reward(phi0, vel0, p.phi[live], p.vel[live],
                                             p.effort[live], self.target[live], p.period))
        terminated = np.zeros(live.size, dtype=bool)
        if failed:
            terminated = np.isin(live, np.fromiter(failed, dtype=np.int64))
        limit = self.max_episode_steps
        truncated = (~terminated & (self.steps[live] >= limit) if limit is not None
                     else np.zeros(live.size, dtype=bool))
        for j in live[terminated].tolist():
            self.ended[j] = f'terminated: {failed[j]}'
        for j in live[truncated].tolist():
            self.ended[j] = f'truncated after {limit} steps'
        return self.observe(live), reward, terminated, truncated, failed

    def _keep(self, ids: IntArray) -> None:
        """Keep the state and effort of the environments ``ids`` as their sample ``steps``."""
        if not self.keeps_samples:
            return
        at = self.steps[ids]
        need = int(at.max()) + 1
        if need > self._samples.shape[1]:   # grow by doubling: a copy per doubling
            grown = np.zeros((3, max(need, 2 * self._samples.shape[1], 16), self.size))
            grown[:, :self._samples.shape[1]] = self._samples
            self._samples = grown
        p = self.pendulums
        self._samples[0, at, ids] = p.phi[ids]
        self._samples[1, at, ids] = p.vel[ids]
        self._samples[2, at, ids] = p.effort[ids]

    @staticmethod
    def _times(config: JointConfig, count: int) -> FloatArray:
        """Return the stamps of ``count`` period starts from the joint's epoch (s)."""
        k = config.period_steps
        return np.array([stamp_ns(config.epoch_ns, j * k, config.h) / 1e9
                         for j in range(count)])

    def end_info(self, ended: IntArray) -> tuple[dict[str, NDArray[Any]], NDArray[np.bool_]]:
        """Return what ``info`` carries for the environments whose episodes ``ended`` this step.

        Per field of :class:`~pendulum_sim.testing.swing_up.metrics.SwingUpMetrics` an array
        over ``ended`` (the module's definitions, over the samples the module docstring
        names), and which of them were measured: none for a task without a goal or with
        ``episode_metrics=False`` (no fields then), nor where the samples cannot be measured
        (a joint that failed with a state that is not finite).
        """
        goal = self.task.goal
        if not self.keeps_samples or goal is None or ended.size == 0:
            return {}, np.zeros(ended.size, dtype=bool)
        groups: dict[tuple[int, int, float, int], list[int]] = {}
        for n, i in enumerate(ended.tolist()):
            c = self.pendulums.configs[i]
            assert c is not None   # an episode ran in it
            groups.setdefault((int(self.steps[i]) + 1, c.epoch_ns, c.h, c.period_steps),
                              []).append(n)
        columns: dict[str, NDArray[Any]] = {}
        measured = np.zeros(ended.size, dtype=bool)
        for (count, _, _, _), rows in groups.items():
            ids = ended[rows]
            config = self.pendulums.configs[int(ids[0])]
            assert config is not None
            # One contiguous row per episode, as a run alone is measured (the same sums).
            phi, vel, effort = (np.ascontiguousarray(self._samples[r, :count][:, ids].T)
                                for r in range(3))
            found, ok = swing_up_metrics_columns(self._times(config, count), phi, vel, effort,
                                                 goal=goal,
                                                 effort_limit=self.pendulums.limit[ids])
            for name, values in found.items():
                if name not in columns:
                    columns[name] = np.zeros(ended.size, dtype=values.dtype)
                columns[name][rows] = values
            measured[rows] = ok
        return columns, measured

    def check_running(self, i: int) -> None:
        """Refuse to step environment ``i`` before its first reset or after its episode."""
        if self.index[i] < 0:
            raise GymError('step() before reset(): call reset() first')
        if self.ended[i]:
            raise GymError(f'step() after the episode ended ({self.ended[i]}): call reset() '
                           'first')
