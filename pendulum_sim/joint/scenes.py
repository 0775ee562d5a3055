"""Find scene files: ``config/<name>.yaml`` parameter files, installed or in the source tree.

A scene is an ordinary ROS 2 parameter file (``/**: ros__parameters: ...``), so
``--ros-args --params-file`` takes it as well as ``pendulum_node --scene NAME``.
"""
from __future__ import annotations

import difflib
import functools
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from pendulum_sim.dds import config_dirs

from .errors import SceneError


def available_scenes() -> list[str]:
    """Return the names of all scenes found, sorted."""
    return sorted({p.stem for folder in config_dirs() for p in folder.glob('*.yaml')})


def find_scene(name: str) -> Path:
    """Return the parameter file of scene ``name`` (a scene name or a path to a YAML file)."""
    candidate = Path(name)
    if candidate.suffix in ('.yaml', '.yml'):
        if candidate.is_file():
            return candidate.resolve()
        raise SceneError(f"scene file '{name}' does not exist")
    if not name or '/' in name or name.startswith('.'):
        raise SceneError(f'scene must be a name like default or a .yaml path, got {name!r}')
    for folder in config_dirs():
        path = folder / f'{name}.yaml'
        if path.is_file():
            return path
    known = ', '.join(available_scenes()) or 'none found'
    raise SceneError(f"unknown scene '{name}'; known scenes: {known}")


# ---------------------------------------------------------------- parameter files and names
# Parameters rclpy declares on every node, and the prefix of its QoS overrides.
ROS_PARAMETERS = ('use_sim_time', 'start_type_description_service')
QOS_OVERRIDES = 'qos_overrides.'
NODE_NAME = 'pendulum_node'


@functools.cache
def known_parameters() -> tuple[str, ...]:
    """Return the parameter names pendulum_node declares (and rclpy declares on every node).

    Sorted, made once per process (the names are the node's declarations, fixed in the code).
    """
    from .parameters import SPEC_BY_NAME

    return tuple(sorted(set(SPEC_BY_NAME) | set(ROS_PARAMETERS)))


def unknown_parameter(name: str, where: str,
                      known: tuple[str, ...] | None = None) -> str | None:
    """Return why ``name`` is not a parameter of the node (with the closest known name), or None.

    ``where`` says where the name came from, e.g. ``scene.yaml`` or ``-p gama:=5.0``.
    """
    known = known_parameters() if known is None else known
    if name in known or name.startswith(QOS_OVERRIDES):
        return None
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    hint = f" (did you mean '{close[0]}'?)" if close else ''
    return f"unknown parameter '{name}' in {where}{hint}"


def is_own_section(key: str) -> bool:
    """Return True if a parameter file's node key can apply to pendulum_node.

    ``/**``, ``pendulum_node`` and fully qualified or wildcard forms ending in ``pendulum_node``
    or ``*``/``**``; sections of other nodes are left to them.
    """
    last = key.rstrip('/').rsplit('/', 1)[-1]
    return last in (NODE_NAME, '*', '**')


def _flatten(prefix: str, tree: Mapping[Any, Any], out: dict[str, Any]) -> None:
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            _flatten(f'{name}.', value, out)
        else:
            out[name] = value


def read_params_file(path: Path, label: str | None = None) -> dict[str, Any]:
    """Read a ROS 2 parameter file and return pendulum_node's parameters in it (flat names).

    Raises SceneError with the reason when the file cannot be read, is not YAML, is not a
    mapping of node names to ``{ros__parameters: {...}}``, or names a parameter the node does
    not have (sections of other nodes are not checked). ``label`` names the file in messages
    (default: its file name).
    """
    label = label or path.name
    if not path.is_file():
        raise SceneError(f"parameter file '{label}' does not exist")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"cannot read parameter file '{label}': {exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        problem = getattr(exc, 'problem', None) or str(exc).splitlines()[0]
        at = f' at line {mark.line + 1}, column {mark.column + 1}' if mark is not None else ''
        raise SceneError(f'{label} is not valid YAML: {problem}{at}') from None
    if not isinstance(data, dict):
        kind = 'nothing' if data is None else f'a {type(data).__name__}'
        raise SceneError(f'{label} must map node names to {{ros__parameters: {{...}}}}, got '
                         f'{kind}')
    values: dict[str, Any] = {}
    known = known_parameters()
    for key, section in data.items():
        if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'), dict):
            raise SceneError(f"{label}: section '{key}' must hold ros__parameters: "
                             '{name: value, ...}')
        if not is_own_section(str(key)):
            continue
        flat: dict[str, Any] = {}
        _flatten('', section['ros__parameters'], flat)
        for name in flat:
            reason = unknown_parameter(name, label, known)
            if reason:
                raise SceneError(reason)
        values.update(flat)
    return values
