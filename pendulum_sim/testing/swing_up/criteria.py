"""The swing-up benchmark's criteria, each a campaign of the swing-up task.

The criteria of the open torque-limited simple-pendulum benchmarks (Wiebe et al., "Open
Source Torque-Limited Simple Pendulum", 2022; the ``double_pendulum`` benchmark's
``benchmark_controller``): every episode starts on the task's scene (``swing_up``: hanging at
rest, torque limit half of m g l) and swings up when it enters the goal box and stays there
to its end (the requirement ``stays == 1``):

- ``nominal``: one episode from the scene's start; ``swing_up_time``, ``energy`` and
  ``smoothness`` are the mean over its runs (one: the simulation is deterministic);
- ``consistency``: starts drawn uniformly from φ0 in [−π, π], φ0' in [−3π, 3π] rad/s;
- ``robustness``: four torque pulses of 1 s during the swing-up (starting at 0.5, 2.0, 3.5
  and 5.0 s), each of a size drawn uniformly from ± half the torque limit;
- ``sensitivity``: the body changed without the controller knowing: m and l each by a
  factor drawn from [0.9, 1.1] (the inertia following, ``I − m l²`` kept), the damping γ
  by a factor from [0.5, 1.5] and a Coulomb friction from [0, 5 %] of the torque limit;
- ``torque_limit``: the nominal episode under each of ``limits`` torque limits from
  ``1/limits`` of the scene's limit up to it; ``min_torque_limit`` is the smallest limit from
  which every larger one on the list swings up;
- ``roa``: a ``roa_grid`` × ``roa_grid`` grid of start states (cell centres) over
  ``roa_span``; ``roa_area`` is the area of the cells whose episode swings up.

``frequency`` (controller calls per second) is measured on the nominal run outside the
campaigns (:mod:`.benchmark`). Each criterion's episodes are drawn from the benchmark's seed
(the campaign's seed, and the sensitivity's bodies from ``seed`` too), so a benchmark is
reproduced by its settings.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import yaml

from ..errors import BenchmarkError
from .metrics import BOX, GOAL, check_box

CRITERIA = ('nominal', 'consistency', 'robustness', 'sensitivity', 'torque_limit', 'roa')
KEYS = ('swing_up_time', 'energy', 'smoothness', 'consistency', 'robustness', 'sensitivity',
        'min_torque_limit', 'frequency', 'roa_area')
UNITS = {'swing_up_time': 's', 'energy': 'J', 'smoothness': 'N m', 'consistency': '%',
         'robustness': '%', 'sensitivity': '%', 'min_torque_limit': 'N m',
         'frequency': 'calls/s', 'roa_area': 'rad^2/s'}
REQUIREMENT = 'stays == 1'
PULSE_STARTS = (0.5, 2.0, 3.5, 5.0)   # s: the robustness pulses
PULSE_DURATION = 1.0                   # s
PULSE_SHARE = 0.5                      # of the torque limit: the pulses' largest size
MASS_SPAN = LENGTH_SPAN = (0.9, 1.1)   # factors of the scene's m and l
DAMPING_SPAN = (0.5, 1.5)              # factor of the scene's gamma
FRICTION_SHARE = 0.05                  # of the torque limit: the largest Coulomb friction
MAX_EPISODES = 1000                    # per drawn criterion (the sensitivity's lists)
MAX_GRID = 200
ROA_GRID = 50                          # start states per axis
LIMITS = 20                            # torque limits on the torque_limit criterion's list
TAU = 2.0 * math.pi
ROA_SPAN = ((0.0, TAU), (-3.0 * math.pi, 3.0 * math.pi))


@dataclass(frozen=True)
class Settings:
    """What a benchmark runs: the controller, the task's joint and each criterion's size.

    Parameters
    ----------
    controller : str or tuple of str
        ``module:function`` (a law, vectorised or not) or a command line (a ROS node).
    scene : str
        The task's joint (``swing_up`` by default).
    duration : float
        Simulated seconds per episode.
    episodes : int
        Episodes of ``consistency``, ``robustness`` and ``sensitivity`` each.
    seed : int
        The seed every drawn criterion is drawn from.
    goal_box : (float, float)
        The goal box around upright (rad, rad/s).
    torque_limit : float, optional
        The torque limit (N m); the scene's ``max_effort`` where None.
    criteria : tuple of str
        The criteria to run (:data:`CRITERIA`).
    roa_grid : int
        Start states per axis of the region-of-attraction grid.
    roa_span : ((float, float), (float, float))
        The grid's angle (rad) and rate (rad/s) ranges.
    limits : int
        Torque limits on the ``torque_limit`` criterion's list.
    jit : bool
        Run a vectorised law's batches on the compiled sweep (numba).
    """

    controller: str | tuple[str, ...]
    scene: str = 'swing_up'
    duration: float = 10.0
    episodes: int = 100
    seed: int = 0
    goal_box: tuple[float, float] = BOX
    torque_limit: float | None = None
    criteria: tuple[str, ...] = CRITERIA
    roa_grid: int = ROA_GRID
    roa_span: tuple[tuple[float, float], tuple[float, float]] = ROA_SPAN
    limits: int = LIMITS
    jit: bool = False
    episode_timeout: float = 600.0
    base: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)


def check_settings(s: Settings) -> None:
    """Refuse settings no benchmark could run, each with a one-line reason (BenchmarkError)."""
    unknown = [c for c in s.criteria if c not in CRITERIA]
    if unknown:
        raise BenchmarkError(f'unknown criterion {unknown[0]!r}; criteria: {", ".join(CRITERIA)}')
    if not s.criteria:
        raise BenchmarkError(f'no criterion to run; criteria: {", ".join(CRITERIA)}')
    twice = [c for i, c in enumerate(s.criteria) if c in s.criteria[:i]]
    if twice:
        raise BenchmarkError(f'criterion {twice[0]!r} is given twice')
    try:
        check_box(GOAL, s.goal_box)
    except Exception as exc:
        raise BenchmarkError(f'goal box: {exc}') from None
    if not (math.isfinite(s.duration) and s.duration > 0):
        raise BenchmarkError(f'duration must be a finite number of seconds > 0, got '
                             f'{s.duration}')
    if not 1 <= s.episodes <= MAX_EPISODES:
        raise BenchmarkError(f'episodes must be in [1, {MAX_EPISODES}], got {s.episodes}')
    if not 2 <= s.roa_grid <= MAX_GRID:
        raise BenchmarkError(f'roa_grid must be in [2, {MAX_GRID}], got {s.roa_grid}')
    if not 2 <= s.limits <= MAX_EPISODES:
        raise BenchmarkError(f'limits must be in [2, {MAX_EPISODES}], got {s.limits}')
    for name, (lo, hi) in zip(('angle', 'rate'), s.roa_span, strict=True):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise BenchmarkError(f'roa_span {name} must be finite with low < high, got '
                                 f'[{lo}, {hi}]')
    if s.torque_limit is not None and not (math.isfinite(s.torque_limit) and
                                           s.torque_limit > 0):
        raise BenchmarkError(f'torque limit must be a finite number of N m > 0, got '
                             f'{s.torque_limit}')
    if s.seed < 0:
        raise BenchmarkError(f'seed must be >= 0, got {s.seed}')


def torque_limit(s: Settings) -> float:
    """Return the task's torque limit (N m): the settings' or the scene's ``max_effort``."""
    limit = s.torque_limit if s.torque_limit is not None else float(s.base['max_effort'])
    if not (math.isfinite(limit) and limit > 0.0):
        raise BenchmarkError(f'the swing-up task needs a torque limit > 0 N m; scene '
                             f'{s.scene!r} has max_effort = {limit:g}')
    return limit


def periods(s: Settings) -> int:
    """Return the control periods of one episode: ``duration`` times the control rate."""
    return max(1, round(s.duration * float(s.base['publish_rate'])))


def _cells(lo: float, hi: float, n: int) -> list[float]:
    """Return the grid of ``n`` cell centres of [lo, hi] as [low, high, n] (grid bounds)."""
    width = (hi - lo) / n
    return [lo + width / 2.0, hi - width / 2.0, n]


def cell_area(s: Settings) -> float:
    """Return the area of one region-of-attraction cell (rad²/s)."""
    (a0, a1), (r0, r1) = s.roa_span
    return (a1 - a0) / s.roa_grid * (r1 - r0) / s.roa_grid


def bodies(s: Settings) -> dict[str, list[float]]:
    """Return the sensitivity's bodies: per episode m, l, inertia, gamma, friction (drawn from
    ``seed``; the inertia keeps the scene's ``I − m l²``)."""
    rng = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(38,)))
    b = s.base
    m0, l0, i0 = float(b['m']), float(b['l']), float(b['inertia'])
    m = m0 * rng.uniform(*MASS_SPAN, s.episodes)
    length = l0 * rng.uniform(*LENGTH_SPAN, s.episodes)
    gamma = float(b['gamma']) * rng.uniform(*DAMPING_SPAN, s.episodes)
    friction = rng.uniform(0.0, FRICTION_SHARE * torque_limit(s), s.episodes)
    inertia = m * length ** 2 + (i0 - m0 * l0 ** 2)
    return {'m': m.tolist(), 'l': length.tolist(), 'inertia': inertia.tolist(),
            'gamma': gamma.tolist(), 'friction': friction.tolist()}


def limits_list(s: Settings) -> list[float]:
    """Return the torque limits of the ``torque_limit`` criterion, smallest first (N m)."""
    top = torque_limit(s)
    return [top * k / s.limits for k in range(1, s.limits + 1)]


def campaign(s: Settings, criterion: str) -> dict[str, Any]:
    """Return the campaign file (as a mapping) of ``criterion``."""
    limit = torque_limit(s)
    body: dict[str, Any] = {
        'controller': list(s.controller) if isinstance(s.controller, tuple) else s.controller,
        'scene': s.scene, 'task': 'swing_up', 'target': GOAL,
        'goal_box': [float(s.goal_box[0]), float(s.goal_box[1])], 'seed': s.seed,
        'periods': periods(s), 'requirements': [REQUIREMENT],
        'episode_timeout': s.episode_timeout}
    if s.jit:
        body['jit'] = True
    params: dict[str, Any] = {}
    if s.torque_limit is not None:
        params['max_effort'] = limit
    if criterion == 'nominal':
        body['episodes'] = 1
    elif criterion == 'consistency':
        body['episodes'] = s.episodes
        params['phi0'] = {'distribution': 'uniform', 'low': -math.pi, 'high': math.pi}
        params['dphi0'] = {'distribution': 'uniform', 'low': -3 * math.pi, 'high': 3 * math.pi}
    elif criterion == 'robustness':
        body['episodes'] = s.episodes
        size = PULSE_SHARE * limit
        body['disturbances'] = [
            {'torque': {'distribution': 'uniform', 'low': -size, 'high': size},
             'start': start, 'duration': PULSE_DURATION} for start in PULSE_STARTS]
    elif criterion == 'sensitivity':
        body['episodes'] = s.episodes
        params.update(bodies(s))
    elif criterion == 'torque_limit':
        body['episodes'] = s.limits
        params['max_effort'] = limits_list(s)
    elif criterion == 'roa':
        (a0, a1), (r0, r1) = s.roa_span
        body['episodes'] = s.roa_grid ** 2
        body['keep_failures'] = False   # the start states that fail are the map, not faults
        params['phi0'] = {'grid': _cells(a0, a1, s.roa_grid)}
        params['dphi0'] = {'grid': _cells(r0, r1, s.roa_grid), 'stride': s.roa_grid}
    else:   # check_settings refuses it first
        raise BenchmarkError(f'unknown criterion {criterion!r}')
    if params:
        body['parameters'] = params
    return body


def campaign_text(s: Settings, criterion: str) -> str:
    """Return the campaign file of ``criterion`` as YAML (floats written exactly)."""
    return yaml.safe_dump(campaign(s, criterion), sort_keys=False, width=99)


def described(s: Settings, criterion: str) -> dict[str, Any]:
    """Return the parameters of ``criterion`` as they go into ``benchmark.yaml``."""
    limit = torque_limit(s)
    common: dict[str, Any] = {'episodes': campaign(s, criterion)['episodes']}
    if criterion == 'nominal':
        common.update({'phi0': float(s.base['phi0']), 'dphi0': float(s.base['dphi0'])})
    elif criterion == 'consistency':
        common.update({'phi0': [-math.pi, math.pi], 'dphi0': [-3 * math.pi, 3 * math.pi]})
    elif criterion == 'robustness':
        common.update({'pulse_starts': list(PULSE_STARTS), 'pulse_duration': PULSE_DURATION,
                       'pulse_torque': [-PULSE_SHARE * limit, PULSE_SHARE * limit]})
    elif criterion == 'sensitivity':
        b = s.base
        common.update({'m': [MASS_SPAN[0] * float(b['m']), MASS_SPAN[1] * float(b['m'])],
                       'l': [LENGTH_SPAN[0] * float(b['l']), LENGTH_SPAN[1] * float(b['l'])],
                       'gamma': [DAMPING_SPAN[0] * float(b['gamma']),
                                 DAMPING_SPAN[1] * float(b['gamma'])],
                       'friction': [0.0, FRICTION_SHARE * limit]})
    elif criterion == 'torque_limit':
        common['limits'] = limits_list(s)
    elif criterion == 'roa':
        common.update({'grid': s.roa_grid, 'phi0': list(s.roa_span[0]),
                       'dphi0': list(s.roa_span[1]), 'cell_area': cell_area(s)})
    return common
