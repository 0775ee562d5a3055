"""Find scene files: ``config/<name>.yaml`` parameter files, installed or in the source tree.

A scene is an ordinary ROS 2 parameter file (``/**: ros__parameters: ...``), so
``--ros-args --params-file`` takes it as well as ``pendulum_node --scene NAME``.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from .errors import SceneError

PACKAGE = 'pendulum_sim'


def scene_dirs() -> list[Path]:
    """Return the folders searched for scenes, in order, existing ones only.

    The package's share folder found through the ament index (a colcon workspace), the
    interpreter prefix's share folder (a pip install) and the source tree (an editable install).
    """
    found: list[Path] = []
    if os.environ.get('AMENT_PREFIX_PATH'):
        try:
            from ament_index_python.packages import (
                PackageNotFoundError,
                get_package_share_directory,
            )
            try:
                found.append(Path(get_package_share_directory(PACKAGE)) / 'config')
            except PackageNotFoundError:
                pass
        except ImportError:  # pragma: no cover - ament_index_python ships with rclpy
            pass
    found.append(Path(sys.prefix) / 'share' / PACKAGE / 'config')
    found.append(Path(__file__).resolve().parents[2] / 'config')
    unique: list[Path] = []
    for folder in found:
        if folder.is_dir() and folder not in unique:
            unique.append(folder)
    return unique


def available_scenes() -> list[str]:
    """Return the names of all scenes found, sorted."""
    return sorted({p.stem for folder in scene_dirs() for p in folder.glob('*.yaml')})


def find_scene(name: str) -> Path:
    """Return the parameter file of scene ``name`` (a scene name or a path to a YAML file)."""
    candidate = Path(name)
    if candidate.suffix in ('.yaml', '.yml'):
        if candidate.is_file():
            return candidate.resolve()
        raise SceneError(f"scene file '{name}' does not exist")
    if not name or '/' in name or name.startswith('.'):
        raise SceneError(f'scene must be a name like default or a .yaml path, got {name!r}')
    for folder in scene_dirs():
        path = folder / f'{name}.yaml'
        if path.is_file():
            return path
    known = ', '.join(available_scenes()) or 'none found'
    raise SceneError(f"unknown scene '{name}'; known scenes: {known}")
