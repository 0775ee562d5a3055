"""What each episode of an environment runs with: a scene, campaign spaces and their draws.

An environment is a scene (any scene name or parameter file, as ``pendulum_node --scene``) and
campaign spaces (``parameters``: node parameter names mapped to a value, a list taken in
episode order or a distribution, as a campaign file's ``parameters``; or the path of a
campaign file, whose ``parameters``, ``target`` and ``scene`` are taken). The spaces are read
by the campaign's own parser and drawn by its own rule
(:func:`pendulum_sim.testing.campaign.scenarios.episode_scenario`): after ``reset(seed=s)``
the environment's episode ``k`` (``k = 0`` for that reset, then one more per ``reset()``)
runs with the parameters and target of episode ``k`` of a campaign seeded ``s``.

:meth:`Scenarios.episodes` draws the episodes of many environments at once (a vector
environment's reset and autoreset): their draws over arrays
(:func:`~pendulum_sim.testing.campaign.scenarios.episode_scenarios`), one joint configuration
for the episodes that differ only in their start state, checked once, and their start states
checked together (:func:`~pendulum_sim.joint.parameters.check_states`).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import JointConfig
from pendulum_sim.joint.parameters import check_states, joint_config

from .errors import GymError

# Any importable law with a keyword target: the campaign parser needs a controller to accept a
# target that varies; the environments never call it.
_PARSE_CONTROLLER = 'pendulum_sim.testing.examples:pd'
FLOAT_KEYWORDS = ('h', 'control_period')
STATE = ('phi0', 'dphi0')   # what episodes of one joint configuration may differ in
IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Episode:
    """One episode's node parameters, joint configuration and target (rad)."""

    values: dict[str, Any]
    config: JointConfig
    target: float


@dataclass(frozen=True)
class Drawn:
    """Many episodes drawn at once: their start states, targets and configurations.

    Attributes
    ----------
    seeds, indices : lists of int
        Each episode's seed and number.
    phi0, dphi0, target : numpy arrays
        Each episode's start state (rad, rad/s) and target (rad).
    groups : list of (JointConfig, numpy array)
        The episodes (their rows) of each joint configuration; the configuration's start
        state is its first episode's.
    columns : dict
        Each scenario parameter's drawn values, one per episode.
    base : dict
        The node parameters the draws replace (the scene and the fixed keywords).
    group_of : numpy array
        Each episode's index in ``groups``.
    """

    seeds: list[int]
    indices: list[int]
    phi0: FloatArray
    dphi0: FloatArray
    target: FloatArray
    groups: list[tuple[JointConfig, IntArray]]
    columns: dict[str, Any]
    base: dict[str, Any]
    group_of: IntArray

    def episode(self, row: int) -> Episode:
        """Return the episode of row ``row`` as :meth:`Scenarios.episode` gives it."""
        values = dict(self.base)
        values.update({name: _item(col[row]) for name, col in self.columns.items()})
        config = dataclasses.replace(self.groups[int(self.group_of[row])][0],
                                     phi0=float(self.phi0[row]), dphi0=float(self.dphi0[row]))
        return Episode(values, config, float(self.target[row]))


def _item(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value


class Scenarios:
    """The episodes of an environment: a scene, its fixed keywords and campaign spaces.

    Parameters
    ----------
    scene : str or None
        A scene name or parameter file; None takes the campaign file's scene, else
        ``default_scene``.
    parameters : mapping, str, path or None
        Campaign spaces over node parameters, or a campaign file.
    integrator, h, control_period : optional
        The node's ``integrator``, ``h`` (s) and ``1/publish_rate`` (s); they win over the
        scene and the spaces.
    defaults : mapping
        The environment's own spaces, under the given ones (a name given replaces it).
    target : number, list or mapping
        The target's space when ``parameters`` is not a campaign file.
    """

    def __init__(self, scene: str | None, parameters: Mapping[str, Any] | str | Path | None,
                 integrator: str | None, h: float | None, control_period: float | None, *,
                 default_scene: str, defaults: Mapping[str, Any],
                 target: Any = 0.0) -> None:
        from pendulum_sim.testing.campaign.spec import parse_spec, read_spec
        from pendulum_sim.testing.errors import TestingError
        from pendulum_sim.testing.scene import scene_values

        spaces: dict[str, Any] = dict(defaults)
        if isinstance(parameters, (str, Path)):
            try:
                spec_file = read_spec(parameters)
            except TestingError as exc:
                raise GymError(str(exc)) from None
            scene = spec_file.scene if scene is None else scene
            data = yaml.safe_load(spec_file.text)
            spaces.update(data.get('parameters') or {})
            target = data['target']  # the target's space, read by the campaign's parser
        elif parameters is not None:
            if not isinstance(parameters, Mapping):
                raise GymError(f'parameters must map node parameter names to values, lists or '
                               f'distributions, or name a campaign file, got {parameters!r}')
            spaces.update(parameters)
        self.scene = default_scene if scene is None else scene
        fixed: dict[str, Any] = {}
        if integrator is not None:
            fixed['integrator'] = integrator
        for name, value in (('h', h), ('control_period', control_period)):
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
                    math.isfinite(value) and value > 0):
                raise GymError(f'{name} must be a positive number of seconds, got {value!r}')
            fixed['h' if name == 'h' else 'publish_rate'] = (
                float(value) if name == 'h' else 1.0 / float(value))
        clash = sorted(set(fixed) & set(spaces))
        if clash:
            raise GymError(f'{clash[0]} is given both as a keyword and in parameters')
        text = yaml.safe_dump({'controller': _PARSE_CONTROLLER, 'scene': self.scene,
                               'episodes': 1, 'periods': 1, 'target': target,
                               'parameters': spaces}, sort_keys=False)
        try:
            self.spec = parse_spec(text, 'parameters')
            self.base = scene_values(self.scene, fixed)
            # Every value a space can give, checked once as the campaign's episodes are.
            for name, space in self.spec.parameters:
                for item in space if isinstance(space, tuple) else (space,):
                    if not hasattr(item, 'kind'):
                        scene_values(self.scene, {**fixed, name: item})
        except TestingError as exc:
            raise GymError(str(exc)) from None
        self.fixed = fixed
        self._floats = {name for name, v in self.base.items() if isinstance(v, float)}
        from pendulum_sim.testing.campaign.spec import varies

        self._varies = {name: varies(space) for name, space in self.spec.parameters}

    def varies(self, name: str) -> bool:
        """Return True when the spaces can give parameter ``name`` different values."""
        from pendulum_sim.testing.campaign.spec import varies

        return any(n == name and varies(s) for n, s in self.spec.parameters)

    def first(self) -> Episode:
        """Return episode 0 of seed 0 (what fixes the spaces of the environment)."""
        return self.episode(0, 0)

    def episode(self, seed: int, index: int) -> Episode:
        """Return episode ``index`` of a campaign seeded ``seed`` (the campaign's draw)."""
        return self.episodes([seed], [index]).episode(0)

    def episodes(self, seeds: list[int], indices: list[int]) -> Drawn:
        """Return the episodes ``indices[i]`` of seeds ``seeds[i]``, drawn and checked at once.

        The first episode that cannot run raises GymError (``episode k of seed s: why``).
        """
        from pendulum_sim.testing.campaign.scenarios import episode_scenarios
        from pendulum_sim.testing.scene import epoch_ns

        drawn = episode_scenarios(self.spec, indices, seeds)
        size = len(indices)
        columns: dict[str, Any] = {}
        for name, col in drawn.values.items():
            # As scene_values types an override: an int where a float is wanted is a float.
            columns[name] = (col if isinstance(col, np.ndarray) or name not in self._floats
                             else [float(v) if isinstance(v, int) and not isinstance(v, bool)
                                   else v for v in col])
        phi0, dphi0 = (np.asarray(columns[name], dtype=np.float64) if name in columns
                       else np.full(size, float(self.base[name])) for name in STATE)
        # The episodes of one configuration: alike in every drawn value but the start state.
        keyed = [name for name in columns if name not in STATE and self._varies[name]]
        rows_of: dict[tuple[Any, ...], list[int]] = {}
        for row, key in enumerate(zip(*(columns[name] for name in keyed), strict=True)
                                  if keyed else [()] * size):
            rows_of.setdefault(tuple(_item(v) for v in key), []).append(row)
        groups: list[tuple[JointConfig, IntArray]] = []
        refused: list[tuple[int, str]] = []
        for rows in rows_of.values():
            first = rows[0]
            values = dict(self.base)
            values.update({name: _item(col[first]) for name, col in columns.items()})
            mine = np.array(rows, dtype=np.int64)
            found = check_states(values, phi0[mine], dphi0[mine])
            if found is not None:
                refused.append((rows[found[0]], found[1]))
                continue
            try:
                config = joint_config(values, epoch_ns(values))
            except JointError as exc:
                refused.append((first, str(exc)))
                continue
            groups.append((config, mine))
        if refused:
            row, reason = min(refused)
            raise GymError(f'episode {indices[row]} of seed {seeds[row]}: {reason}')
        group_of = np.empty(size, dtype=np.int64)
        for g, (_, rows_g) in enumerate(groups):
            group_of[rows_g] = g
        return Drawn(list(seeds), list(indices), phi0, dphi0, drawn.target, groups, columns,
                     self.base, group_of)
