"""What each episode of an environment runs with: a scene, campaign spaces and their draws.

An environment is a scene (any scene name or parameter file, as ``pendulum_node --scene``) and
campaign spaces (``parameters``: node parameter names mapped to a value, a list taken in
episode order or a distribution, as a campaign file's ``parameters``; or the path of a
campaign file, whose ``parameters``, ``target`` and ``scene`` are taken). The spaces are read
by the campaign's own parser and drawn by its own rule
(:func:`pendulum_sim.testing.campaign.scenarios.episode_scenario`): after ``reset(seed=s)``
the environment's episode ``k`` (``k = 0`` for that reset, then one more per ``reset()``)
runs with the parameters and target of episode ``k`` of a campaign seeded ``s``.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from pendulum_sim.joint.errors import JointError
from pendulum_sim.joint.joint import JointConfig
from pendulum_sim.joint.parameters import check, joint_config

from .errors import GymError

# Any importable law with a keyword target: the campaign parser needs a controller to accept a
# target that varies; the environments never call it.
_PARSE_CONTROLLER = 'pendulum_sim.testing.examples:pd'
FLOAT_KEYWORDS = ('h', 'control_period')


@dataclass(frozen=True)
class Episode:
    """One episode's node parameters, joint configuration and target (rad)."""

    values: dict[str, Any]
    config: JointConfig
    target: float


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

    def varies(self, name: str) -> bool:
        """Return True when the spaces can give parameter ``name`` different values."""
        from pendulum_sim.testing.campaign.spec import varies

        return any(n == name and varies(s) for n, s in self.spec.parameters)

    def first(self) -> Episode:
        """Return episode 0 of seed 0 (what fixes the spaces of the environment)."""
        return self.episode(0, 0)

    def episode(self, seed: int, index: int) -> Episode:
        """Return episode ``index`` of a campaign seeded ``seed`` (the campaign's draw)."""
        from pendulum_sim.testing.campaign.scenarios import episode_scenario
        from pendulum_sim.testing.scene import epoch_ns

        drawn = episode_scenario(dataclasses.replace(self.spec, seed=seed), index)
        values = dict(self.base)
        for name, value in drawn.values.items():
            # As scene_values types an override: an int where a float is wanted is a float.
            values[name] = (float(value) if name in self._floats and isinstance(value, int)
                            and not isinstance(value, bool) else value)
        reason = check(values)
        if reason is None:
            try:
                config = joint_config(values, epoch_ns(values))
            except JointError as exc:
                reason = str(exc)
        if reason is not None:
            raise GymError(f'episode {index} of seed {seed}: {reason}')
        return Episode(values, config, drawn.target)
