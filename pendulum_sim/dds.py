"""What every ROS process of the package sets up the same way: DDS on 127.0.0.1, the executor.

Every process of the package that starts rclpy (``pendulum_node``, ``pendulum_replay``,
``pendulum_pd_controller``) calls :func:`use_loopback_profile` before ``rclpy.init``, and the
long-running ones pick their executor with :func:`make_executor`, let it go of their node with
:func:`release` before destroying it with :func:`shut_down`, and end through :func:`exit_with`.
Also where the installed config files (scenes, the DDS profile) are. rclpy is imported only
inside :func:`make_executor` and :func:`shut_down`.
"""
from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, MutableMapping
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from .exit_deadline import exit_deadline

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
    """Keep every DDS socket on 127.0.0.1 when discovery is LOCALHOST; return the profile used.

    With ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and no Fast DDS profile chosen, points both
    ``FASTRTPS_DEFAULT_PROFILES_FILE`` (Fast DDS 2.x, ROS 2 Jazzy) and
    ``FASTDDS_DEFAULT_PROFILES_FILE`` (Fast DDS 3.x) in ``environ`` at the shipped loopback
    profile. With that profile (set here or by the user) the discovery range becomes
    ``SYSTEM_DEFAULT``: the profile does LOCALHOST's discovery itself (unicast announcements to
    127.0.0.1, no multicast), and rmw_fastrtps then adds no UDPv4 transport of its own, whose
    send-only sockets would bind 0.0.0.0. Processes left in LOCALHOST still discover these.
    Nothing changes for another range (``SUBNET`` across hosts) or another profile. Call it
    before ``rclpy.init``.
    """
    if environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '') != 'LOCALHOST':
        return None
    shipped = loopback_profile()
    if shipped is None:
        return None
    chosen = [environ[var] for var in PROFILE_VARIABLES if environ.get(var)]
    if chosen and not all(_same_file(path, shipped) for path in chosen):
        return None
    for var in PROFILE_VARIABLES:
        environ[var] = str(shipped)
    environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
    return shipped


def _same_file(path: str, other: Path) -> bool:
    """Return True when ``path`` is ``other`` or holds the same bytes (an installed copy)."""
    try:
        return Path(path).samefile(other) or Path(path).read_bytes() == other.read_bytes()
    except OSError:
        return False


EXECUTORS = ('events', 'single')


def add_executor_option(parser: argparse.ArgumentParser) -> None:
    """Add the ``--executor`` option (one of :data:`EXECUTORS`) of the programs' parsers."""
    parser.add_argument('--executor', choices=EXECUTORS, default='events',
                        help="rclpy executor: 'events' (the experimental EventsExecutor, "
                        "less CPU per message) or 'single' (SingleThreadedExecutor)")


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


# How long destroying the node and shutting rclpy down may take before the process ends without
# it. Fast DDS 2.14 (ROS 2 Jazzy) deletes a participant with set_listener(nullptr), which spins
# while a discovery callback is in flight and keeps the mutex that callback needs to finish
# (eProsima/Fast-DDS issue #6513). When the peers stop at the same moment (Ctrl-C in a terminal
# or a launch file), their endpoints leaving start such callbacks: here 3 teardowns in 1180
# spun for more than 10 s. A teardown that does not spin took 18-110 ms on this 2-core machine
# while the tests ran.
TEARDOWN_LIMIT = 3.0


def shut_down(node: Node | None, code: int, limit: float = TEARDOWN_LIMIT) -> None:
    """Destroy ``node`` and shut rclpy down; past ``limit`` seconds, end the process with ``code``.

    For a program's own end, where ending the process is what comes next anyway (the package's
    console scripts), never inside a process that must go on. Call it last, once the node's
    work is closed (summary printed, recording written): the deadline
    (:func:`pendulum_sim.exit_deadline.exit_deadline`) ends the process with ``_exit`` from a
    thread of the C library, because the stuck call keeps the GIL. The peers then see the
    participant itself leave only when its lease runs out; the node's publishers and
    subscriptions were destroyed before the participant's deletion began.

    Called from a ``finally`` clause that an exception passes through, the process ends with 1
    instead of 0, as Python would end it (the traceback, which Python prints only once the
    exception has left ``main``, is then lost).
    """
    import rclpy

    if sys.exc_info()[0] is not None and code == 0:
        code = 1  # called from a finally clause an exception goes through: as Python would end
    with exit_deadline(code, limit):
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


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
