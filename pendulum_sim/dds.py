"""What every ROS process of the package sets up the same way: DDS on 127.0.0.1, the executor.

Every process of the package that starts rclpy (``pendulum_node``, ``pendulum_replay``,
``pendulum_pd_controller``) calls :func:`use_loopback_profile` before ``rclpy.init``, and the
long-running ones pick their executor with :func:`make_executor` and let it go of their node
with :func:`release` before destroying it. Also where the installed
config files (scenes, the DDS profile) are. rclpy is imported only inside
:func:`make_executor`.
"""
from __future__ import annotations

import os
import sys
from collections.abc import MutableMapping
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node

PACKAGE = 'pendulum_sim'


def config_dirs() -> list[Path]:
    """Return the folders holding the installed config files (scenes, DDS profile), in order.

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
    found.append(Path(__file__).resolve().parents[1] / 'config')
    unique: list[Path] = []
    for folder in found:
        if folder.is_dir() and folder not in unique:
            unique.append(folder)
    return unique



LOOPBACK_PROFILE = 'fastdds_localhost.xml'
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def loopback_profile() -> Path | None:
    """Return the installed Fast DDS profile that keeps DDS on 127.0.0.1, or None if missing."""
    for folder in config_dirs():
        path = folder / LOOPBACK_PROFILE
        if path.is_file():
            return path
    return None


def use_loopback_profile(environ: MutableMapping[str, str]) -> Path | None:
    """Point Fast DDS at the loopback profile when discovery is LOCALHOST and none is chosen.

    Sets both ``FASTRTPS_DEFAULT_PROFILES_FILE`` (Fast DDS 2.x, ROS 2 Jazzy) and
    ``FASTDDS_DEFAULT_PROFILES_FILE`` (Fast DDS 3.x) in ``environ`` unless either is set, or
    ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is not ``LOCALHOST``. Call it before ``rclpy.init``.
    Returns the profile set, or None when nothing was changed.
    """
    if environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '') != 'LOCALHOST':
        return None
    if any(environ.get(var) for var in PROFILE_VARIABLES):
        return None
    path = loopback_profile()
    if path is None:
        return None
    for var in PROFILE_VARIABLES:
        environ[var] = str(path)
    return path


EXECUTORS = ('events', 'single')


def make_executor(kind: str) -> Executor:
    """Return rclpy's EventsExecutor for ``'events'`` (less CPU per message), else the
    SingleThreadedExecutor."""
    from rclpy.executors import SingleThreadedExecutor

    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:  # pragma: no cover - rclpy before Jazzy 7.1
            pass
    return SingleThreadedExecutor()


def release(executor: Executor | None, node: Node | None) -> None:
    """Make ``executor`` let go of ``node`` and shut it down, before the node is destroyed.

    The EventsExecutor holds callbacks of the node's publisher and subscription events (rclpy
    gives each a QoS-incompatibility handler); a node destroyed while the executor still holds
    them can abort the process at exit ('Destroying callback manager with callbacks remaining',
    measured about once in 100 shutdowns here; rclpy issue #1644).
    """
    if executor is None:
        return
    if node is not None:
        executor.remove_node(node)
    executor.shutdown()
