"""``pendulum_node``'s command line: options, scenes, the executor, and a clean shutdown.

Run it as::

    pendulum_node --scene default
    pendulum_node --ros-args --params-file config/default.yaml
"""
from __future__ import annotations

import argparse
import os
import sys

import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.utilities import remove_ros_args

from pendulum_sim.core import PendulumError

from .errors import NodeError, SceneError
from .pendulum_node import PendulumNode
from .scenes import available_scenes, find_scene
from .status import StatusLine


def _executor(kind: str) -> Executor:
    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:  # pragma: no cover - rclpy before Jazzy 7.1
            pass
    return SingleThreadedExecutor()


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='pendulum_node',
        description='Serve a damped physical pendulum as a real-time simulated ROS 2 joint.',
        epilog='ROS arguments follow --ros-args, e.g. --ros-args --params-file scene.yaml '
               '-p gamma:=2.0')
    parser.add_argument('--scene', help='load the installed scene config/NAME.yaml (or a '
                        'YAML path) before any other ROS parameters')
    parser.add_argument('--list-scenes', action='store_true', help='list the scenes and exit')
    parser.add_argument('--rt-priority', type=int, default=0, metavar='N',
                        help='run with SCHED_FIFO priority N (1-99, as rttest does; needs '
                        'CAP_SYS_NICE); 0 (default) keeps the normal scheduler')
    parser.add_argument('--executor', choices=('events', 'single'), default='events',
                        help="rclpy executor: 'events' (the experimental EventsExecutor, "
                        "less CPU) or 'single' (SingleThreadedExecutor)")
    return parser


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or SIGTERM, then print a summary."""
    argv = list(sys.argv if args is None else args)
    opts = _parser().parse_args(remove_ros_args(argv)[1:])
    if opts.list_scenes:
        print('\n'.join(available_scenes()))
        return 0
    ros_argv = argv
    if opts.scene:
        try:
            path = find_scene(opts.scene)
        except SceneError as exc:
            print(f'pendulum_node: {exc}', file=sys.stderr)
            return 2
        # The scene comes first, so parameters given after --ros-args override it.
        ros_argv = [argv[0], '--ros-args', '--params-file', str(path), '--', *argv[1:]]
    if opts.rt_priority:
        # Before rclpy.init, so the DDS and executor threads inherit the policy.
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(opts.rt_priority))
        except (OSError, ValueError) as exc:
            print(f'pendulum_node: cannot use SCHED_FIFO priority {opts.rt_priority} ({exc}); '
                  'running with the normal scheduler', file=sys.stderr)
    rclpy.init(args=ros_argv)
    node: PendulumNode | None = None
    code = 0
    try:
        executor = _executor(opts.executor)
        node = PendulumNode(status=StatusLine())
        executor.add_node(node)
        # spin_once in a loop rather than spin(): the EventsExecutor's spin() does not return
        # to Python, so it would miss Ctrl-C.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.25)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (NodeError, InvalidParameterValueException, InvalidParameterTypeException) as exc:
        hint = ' (write doubles with a decimal point, e.g. 2.0)' if isinstance(
            exc, InvalidParameterTypeException) else ''
        print(f'pendulum_node: {exc}{hint}', file=sys.stderr)
        code = 2
    except PendulumError as exc:  # e.g. RecorderError: the recording cannot be opened
        print(f'pendulum_node: {exc}', file=sys.stderr)
        code = 2
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
