"""What every ROS process of the package sets up the same way: DDS on 127.0.0.1, the executor.

Every process of the package that starts rclpy (``pendulum_node``, ``pendulum_replay``,
``pendulum_pd_controller``) calls :func:`use_loopback_profile` before ``rclpy.init``, and the
long-running ones pick their executor with :func:`make_executor`, let it go of their node with
:func:`release` before destroying it and end through :func:`exit_with`. Also where the installed
config files (scenes, the DDS profile) are. rclpy is imported only inside
:func:`make_executor`.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Callable, MutableMapping
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

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


_RETIRED: list[Executor] = []  # executors released, kept alive until :func:`exit_with`


def release(executor: Executor | None, node: Node | None) -> None:
    """Make ``executor`` let go of ``node`` and shut it down, before the node is destroyed.

    The executor is kept alive until the process ends (:func:`exit_with`): rclpy's
    EventsExecutor aborts the process when it is destroyed while callbacks of the node's
    entities are still registered with it ('Destroying callback manager with callbacks
    remaining'; rclpy issue #1644), which happened here about once in 100 shutdowns, with and
    without the node removed first.
    """
    if executor is None:
        return
    if node is not None:
        executor.remove_node(node)
    executor.shutdown()
    _RETIRED.append(executor)


def exit_with(main: Callable[[], int]) -> NoReturn:
    """Run a process's ``main`` and end the process with its exit code.

    Where an executor was released, the process ends with ``os._exit`` after flushing stdout
    and stderr, so the executor's destructor never runs (everything else, the node's summary
    and recording included, was closed by ``main``); otherwise with ``sys.exit``.
    """
    code = main()
    if not _RETIRED:
        sys.exit(code)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
